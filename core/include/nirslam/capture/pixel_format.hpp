#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include <opencv2/core/mat.hpp>

namespace nirslam {

// The pixel formats nirslam converts from a camera's buffers. NIR cameras are grey; YUYV and MJPG
// are what many UVC cameras offer besides, and only their luma is kept.
enum class PixelFormat {
  Grey,  // V4L2_PIX_FMT_GREY: 8 bits a pixel
  Y10,   // V4L2_PIX_FMT_Y10: 16-bit little-endian words, value in the low 10 bits
  Y12,   // V4L2_PIX_FMT_Y12: 16-bit little-endian words, value in the low 12 bits
  Y16,   // V4L2_PIX_FMT_Y16: 16-bit little-endian words, all 16 bits
  Yuyv,  // V4L2_PIX_FMT_YUYV: Y0 U Y1 V, luma kept
  Mjpg,  // V4L2_PIX_FMT_MJPEG: one JPEG a frame, decoded to grey
};

std::uint32_t fourcc_of(PixelFormat format);
std::optional<PixelFormat> pixel_format_from_fourcc(std::uint32_t fourcc);
// "GREY", "Y10", "Y12", "Y16", "YUYV", "MJPG" (case-insensitive; "MJPEG" too).
std::optional<PixelFormat> pixel_format_from_name(std::string_view name);
std::string_view to_string(PixelFormat format);
// The four characters of a V4L2 fourcc, trailing blanks removed ("Y10 " -> "Y10").
std::string fourcc_to_string(std::uint32_t fourcc);

// Significant bits of the converted image: 8 for GREY, YUYV, MJPG; 10, 12, 16 for Y10, Y12, Y16.
int bit_depth_of(PixelFormat format);
// Bytes a pixel takes in the buffer (0 for MJPG, which is compressed).
int bytes_per_pixel(PixelFormat format);

// How one buffer is laid out, as negotiated with the driver.
struct BufferLayout {
  PixelFormat format = PixelFormat::Grey;
  int width = 0;
  int height = 0;
  int bytes_per_line = 0;  // the driver's stride; 0 means packed rows
};

// The buffer as a grey image: CV_8UC1 for 8-bit formats, CV_16UC1 with the value in the low
// bits for Y10/Y12/Y16 (the image owns its pixels). Throws std::invalid_argument naming the
// format and sizes when the buffer is too short or an MJPG frame does not decode to that size.
cv::Mat convert_buffer(const BufferLayout& layout, std::span<const std::uint8_t> bytes);

// A side-by-side stereo frame split in its halves; the left one is what SLAM gets.
struct StereoPair {
  cv::Mat left;
  cv::Mat right;
};
// Throws std::invalid_argument when the width is odd.
StereoPair split_side_by_side(const cv::Mat& image);

}  // namespace nirslam
