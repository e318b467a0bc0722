#include "nirslam/capture/pixel_format.hpp"

#include <linux/videodev2.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "nirslam/image/image_codec.hpp"

namespace nirslam {

std::uint32_t fourcc_of(PixelFormat format) {
  switch (format) {
    case PixelFormat::Grey: return V4L2_PIX_FMT_GREY;
    case PixelFormat::Y10: return V4L2_PIX_FMT_Y10;
    case PixelFormat::Y12: return V4L2_PIX_FMT_Y12;
    case PixelFormat::Y16: return V4L2_PIX_FMT_Y16;
    case PixelFormat::Yuyv: return V4L2_PIX_FMT_YUYV;
    case PixelFormat::Mjpg: return V4L2_PIX_FMT_MJPEG;
  }
  return 0;
}

std::optional<PixelFormat> pixel_format_from_fourcc(std::uint32_t fourcc) {
  for (const PixelFormat f : {PixelFormat::Grey, PixelFormat::Y10, PixelFormat::Y12, PixelFormat::Y16,
                              PixelFormat::Yuyv, PixelFormat::Mjpg})
    if (fourcc_of(f) == fourcc) return f;
  if (fourcc == V4L2_PIX_FMT_JPEG) return PixelFormat::Mjpg;  // some UVC cameras call MJPG "JPEG"
  return std::nullopt;
}

std::optional<PixelFormat> pixel_format_from_name(std::string_view name) {
  std::string upper(name);
  std::transform(upper.begin(), upper.end(), upper.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  if (upper == "GREY" || upper == "GRAY" || upper == "Y8") return PixelFormat::Grey;
  if (upper == "Y10") return PixelFormat::Y10;
  if (upper == "Y12") return PixelFormat::Y12;
  if (upper == "Y16") return PixelFormat::Y16;
  if (upper == "YUYV") return PixelFormat::Yuyv;
  if (upper == "MJPG" || upper == "MJPEG") return PixelFormat::Mjpg;
  return std::nullopt;
}

std::string_view to_string(PixelFormat format) {
  switch (format) {
    case PixelFormat::Grey: return "GREY";
    case PixelFormat::Y10: return "Y10";
    case PixelFormat::Y12: return "Y12";
    case PixelFormat::Y16: return "Y16";
    case PixelFormat::Yuyv: return "YUYV";
    case PixelFormat::Mjpg: return "MJPG";
  }
  return "?";
}

std::string fourcc_to_string(std::uint32_t fourcc) {
  std::string text;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xFFu);
    text += std::isprint(static_cast<unsigned char>(c)) != 0 ? c : '?';
  }
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

int bit_depth_of(PixelFormat format) {
  switch (format) {
    case PixelFormat::Y10: return 10;
    case PixelFormat::Y12: return 12;
    case PixelFormat::Y16: return 16;
    default: return 8;
  }
}

int bytes_per_pixel(PixelFormat format) {
  switch (format) {
    case PixelFormat::Grey: return 1;
    case PixelFormat::Y10:
    case PixelFormat::Y12:
    case PixelFormat::Y16:
    case PixelFormat::Yuyv: return 2;
    case PixelFormat::Mjpg: return 0;
  }
  return 0;
}

namespace {

std::string describe(const BufferLayout& layout) {
  return std::string(to_string(layout.format)) + " " + std::to_string(layout.width) + "x" + std::to_string(layout.height);
}

// 16-bit little-endian words; Y10 and Y12 keep their value in the low bits, and bits above the
// format's depth are masked (some bridges leave garbage there).
cv::Mat convert_words(const BufferLayout& layout, std::span<const std::uint8_t> bytes, std::size_t stride) {
  const std::uint16_t mask = static_cast<std::uint16_t>((1u << bit_depth_of(layout.format)) - 1u);
  cv::Mat image(layout.height, layout.width, CV_16UC1);
  for (int y = 0; y < layout.height; ++y) {
    const std::uint8_t* in = bytes.data() + static_cast<std::size_t>(y) * stride;
    auto* out = image.ptr<std::uint16_t>(y);
    for (int x = 0; x < layout.width; ++x)
      out[x] = static_cast<std::uint16_t>((in[2 * x] | (in[2 * x + 1] << 8)) & mask);
  }
  return image;
}

}  // namespace

cv::Mat convert_buffer(const BufferLayout& layout, std::span<const std::uint8_t> bytes) {
  if (layout.width <= 0 || layout.height <= 0)
    throw std::invalid_argument("pixel conversion: empty frame size " + describe(layout));
  if (layout.format == PixelFormat::Mjpg) {
    if (bytes.empty()) throw std::invalid_argument("pixel conversion: empty MJPG frame (" + describe(layout) + ")");
    cv::Mat decoded;
    try {
      decoded = decode_image(bytes, ImageReadMode::Grey);
    } catch (const std::runtime_error& e) {
      throw std::invalid_argument("pixel conversion: MJPG frame of " + std::to_string(bytes.size()) +
                                  " bytes does not decode (" + e.what() + ")");
    }
    if (decoded.cols != layout.width || decoded.rows != layout.height)
      throw std::invalid_argument("pixel conversion: MJPG frame decodes to " + std::to_string(decoded.cols) + "x" +
                                  std::to_string(decoded.rows) + ", negotiated " + describe(layout));
    return decoded;
  }
  const std::size_t packed = static_cast<std::size_t>(layout.width) * bytes_per_pixel(layout.format);
  const std::size_t stride = layout.bytes_per_line > 0 ? static_cast<std::size_t>(layout.bytes_per_line) : packed;
  if (stride < packed)
    throw std::invalid_argument("pixel conversion: bytes per line " + std::to_string(stride) + " is less than a row of " +
                                describe(layout) + " (" + std::to_string(packed) + ")");
  const std::size_t needed = stride * static_cast<std::size_t>(layout.height - 1) + packed;
  if (bytes.size() < needed)
    throw std::invalid_argument("pixel conversion: " + std::to_string(bytes.size()) + " bytes for " + describe(layout) +
                                ", which needs " + std::to_string(needed));
  switch (layout.format) {
    case PixelFormat::Grey: {
      cv::Mat image(layout.height, layout.width, CV_8UC1);
      for (int y = 0; y < layout.height; ++y)
        std::memcpy(image.ptr(y), bytes.data() + static_cast<std::size_t>(y) * stride, packed);
      return image;
    }
    case PixelFormat::Yuyv: {
      cv::Mat image(layout.height, layout.width, CV_8UC1);
      for (int y = 0; y < layout.height; ++y) {
        const std::uint8_t* in = bytes.data() + static_cast<std::size_t>(y) * stride;
        std::uint8_t* out = image.ptr(y);
        for (int x = 0; x < layout.width; ++x) out[x] = in[2 * x];  // Y0 U Y1 V: luma at even bytes
      }
      return image;
    }
    default: return convert_words(layout, bytes, stride);
  }
}

StereoPair split_side_by_side(const cv::Mat& image) {
  if (image.cols % 2 != 0)
    throw std::invalid_argument("side-by-side stereo: frame width " + std::to_string(image.cols) + " is odd");
  const int half = image.cols / 2;
  return {image.colRange(0, half).clone(), image.colRange(half, image.cols).clone()};
}

}  // namespace nirslam
