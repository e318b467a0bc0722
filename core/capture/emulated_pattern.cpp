#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "nirslam/capture/emulated_uvc.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {
namespace {

constexpr int kDriftMargin = 96;   // texture wider and taller than a view by this, for the drift
constexpr int kStereoDisparity = 12;

// Albedo with structure at several scales, built once per view size (drawing it per frame would
// cost more than the capture it stands for).
const cv::Mat& wall_texture(int width, int height) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, cv::Mat> cache;
  const std::lock_guard lock(mutex);
  cv::Mat& texture = cache[{width, height}];
  if (texture.empty()) {
    const int w = width + 2 * kDriftMargin, h = height + 2 * kDriftMargin;
    cv::RNG rng(7);
    texture = cv::Mat(h, w, CV_32FC1, cv::Scalar(0.0f));
    for (int octave = 0; octave < 5; ++octave) {
      const int cell = std::max(2, 128 >> octave);
      cv::Mat coarse(h / cell + 2, w / cell + 2, CV_32FC1);
      rng.fill(coarse, cv::RNG::UNIFORM, 0.0, 1.0);
      cv::Mat fine;
      cv::resize(coarse, fine, cv::Size(coarse.cols * cell, coarse.rows * cell), 0, 0, cv::INTER_CUBIC);
      texture += fine(cv::Rect(0, 0, w, h)) * (0.5 / (octave + 1));
    }
    for (int i = 0; i < 60 + w * h / 4000; ++i) {
      const cv::Point corner(rng.uniform(0, w), rng.uniform(0, h));
      const cv::Size size(rng.uniform(4, std::max(5, w / 8)), rng.uniform(4, std::max(5, h / 8)));
      cv::rectangle(texture, cv::Rect(corner, size), cv::Scalar(rng.uniform(-0.3, 0.3)), cv::FILLED);
    }
    cv::normalize(texture, texture, 0.1, 0.9, cv::NORM_MINMAX);
  }
  return texture;
}

// One view of the wall, as a fraction of full scale: 10 ms at gain 16 puts the mean near mid-grey.
cv::Mat view(const EmulatedFrameRequest& request, int width, int height, int shift_x) {
  const cv::Mat& texture = wall_texture(width, height);
  const double t = request.sequence / 30.0;
  const int dx = kDriftMargin + static_cast<int>(std::lround(0.9 * kDriftMargin * std::sin(0.35 * t))) + shift_x;
  const int dy = kDriftMargin + static_cast<int>(std::lround(0.6 * kDriftMargin * std::sin(0.5 * t + 1.0)));
  const int x0 = std::clamp(dx, 0, texture.cols - width);
  const int y0 = std::clamp(dy, 0, texture.rows - height);
  const double brightness = (request.exposure_100us / 100.0) * (request.gain / 16.0);
  cv::Mat out;
  texture(cv::Rect(x0, y0, width, height)).convertTo(out, CV_32FC1, brightness);
  return out;
}

void write_words(const cv::Mat& fraction, int max_value, const BufferLayout& layout, std::span<std::uint8_t> buffer) {
  const std::size_t stride = layout.bytes_per_line > 0 ? layout.bytes_per_line : layout.width * 2;
  for (int y = 0; y < fraction.rows; ++y) {
    const float* in = fraction.ptr<float>(y);
    std::uint8_t* out = buffer.data() + y * stride;
    for (int x = 0; x < fraction.cols; ++x) {
      const auto v = static_cast<std::uint16_t>(std::lround(std::clamp(in[x], 0.0f, 1.0f) * max_value));
      out[2 * x] = static_cast<std::uint8_t>(v & 0xFFu);
      out[2 * x + 1] = static_cast<std::uint8_t>(v >> 8);
    }
  }
}

}  // namespace

std::size_t draw_emulated_pattern(const EmulatedFrameRequest& request, bool side_by_side, std::span<std::uint8_t> buffer) {
  const BufferLayout& layout = request.layout;
  cv::Mat fraction;
  if (side_by_side) {
    const int half = layout.width / 2;
    cv::hconcat(view(request, half, layout.height, 0), view(request, layout.width - half, layout.height, kStereoDisparity), fraction);
  } else {
    fraction = view(request, layout.width, layout.height, 0);
  }
  const std::size_t stride = layout.bytes_per_line > 0 ? static_cast<std::size_t>(layout.bytes_per_line)
                                                        : static_cast<std::size_t>(layout.width * std::max(1, bytes_per_pixel(layout.format)));
  switch (layout.format) {
    case PixelFormat::Grey:
    case PixelFormat::Yuyv: {
      cv::Mat grey;
      fraction.convertTo(grey, CV_8UC1, 255.0);
      const bool yuyv = layout.format == PixelFormat::Yuyv;
      for (int y = 0; y < grey.rows; ++y) {
        std::uint8_t* out = buffer.data() + y * stride;
        const std::uint8_t* in = grey.ptr(y);
        if (!yuyv) {
          std::memcpy(out, in, grey.cols);
          continue;
        }
        for (int x = 0; x < grey.cols; ++x) {
          out[2 * x] = in[x];
          out[2 * x + 1] = 128;  // neutral chroma: U and V alternate, both grey
        }
      }
      return stride * layout.height;
    }
    case PixelFormat::Y10: write_words(fraction, 1023, layout, buffer); return stride * layout.height;
    case PixelFormat::Y12: write_words(fraction, 4095, layout, buffer); return stride * layout.height;
    case PixelFormat::Y16: write_words(fraction, 65535, layout, buffer); return stride * layout.height;
    case PixelFormat::Mjpg: {
      cv::Mat grey;
      fraction.convertTo(grey, CV_8UC1, 255.0);
      const std::vector<std::uint8_t> jpeg = encode_jpeg(grey, 90);
      if (jpeg.size() > buffer.size()) throw std::length_error("emulated MJPG frame larger than its buffer");
      std::memcpy(buffer.data(), jpeg.data(), jpeg.size());
      return jpeg.size();
    }
  }
  return 0;
}

EmulatedCameraSpec emulated_mono_nir_camera(const std::string& node) {
  EmulatedCameraSpec spec;
  spec.node = node;
  spec.card = "Emulated NIR mono camera";
  spec.bus_info = "usb-0000:00:14.0-1";
  const std::vector<std::pair<int, int>> sizes{{640, 480}, {320, 240}};
  for (const PixelFormat f : {PixelFormat::Grey, PixelFormat::Y10, PixelFormat::Y12, PixelFormat::Y16, PixelFormat::Yuyv,
                              PixelFormat::Mjpg})
    spec.formats.push_back({f, sizes, {60.0, 30.0, 15.0}});
  return spec;
}

EmulatedCameraSpec emulated_stereo_nir_camera(const std::string& node) {
  EmulatedCameraSpec spec;
  spec.node = node;
  spec.card = "Emulated NIR stereo camera";  // V4L2 cards hold 31 characters
  spec.bus_info = "usb-0000:00:14.0-2";
  spec.side_by_side = true;
  spec.formats.push_back({PixelFormat::Grey, {{1280, 480}, {640, 240}}, {30.0, 15.0}});
  spec.formats.push_back({PixelFormat::Y16, {{1280, 480}, {640, 240}}, {30.0, 15.0}});
  spec.auto_exposure_default = true;
  return spec;
}

std::shared_ptr<EmulatedUvc> make_emulated_nir_cameras(bool paced) {
  auto emulator = std::make_shared<EmulatedUvc>();
  EmulatedCameraSpec mono = emulated_mono_nir_camera("/dev/video0");
  EmulatedCameraSpec stereo = emulated_stereo_nir_camera("/dev/video2");
  mono.paced = stereo.paced = paced;
  emulator->add_camera(mono);
  emulator->add_camera(stereo);
  return emulator;
}

}  // namespace nirslam
