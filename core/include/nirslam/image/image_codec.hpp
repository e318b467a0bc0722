#pragma once

// Image files in and out of cv::Mat without OpenCV's imgcodecs: Debian builds that module against
// GDAL, which loads ~118 more shared libraries into every process (0.15-0.2 s per start) and into
// the package's dependencies. PNG goes through libpng, JPEG through libjpeg-turbo, binary PGM/PPM
// is parsed here. These are the only formats the tool reads and writes.
//
// Colour is BGR / BGRA in memory, as OpenCV's own functions (cvtColor, drawing) expect; files hold
// RGB as their formats say. 16-bit samples are in host byte order in memory.

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace nirslam {

enum class ImageReadMode {
  AsStored,  // 8- or 16-bit; grey, grey + alpha, BGR or BGRA as the file holds it
  Grey,      // 8-bit grey whatever the file holds (16-bit keeps its high byte)
  Bgr,       // 8-bit BGR whatever the file holds (alpha dropped)
};

// Format from the leading bytes: PNG, JPEG, binary PGM (P5) or PPM (P6). Throws
// std::runtime_error saying what is wrong (unknown format, truncated or corrupt data); the
// message names no file, callers know which one it was.
cv::Mat decode_image(std::span<const std::uint8_t> bytes, ImageReadMode mode = ImageReadMode::AsStored);

// Throws InputError naming the file: missing, unreadable, empty, or the decoder's reason.
cv::Mat read_image(const std::filesystem::path& file, ImageReadMode mode = ImageReadMode::AsStored);

enum class PngStrategy {
  Default,
  // No string matching: several times faster to encode than any zlib level on camera noise,
  // which deflate's matches barely compress anyway (the session recorder's setting).
  HuffmanOnly,
};

struct PngOptions {
  int compression_level = 1;  // zlib 0-9; 1 is fast and already most of the gain
  PngStrategy strategy = PngStrategy::Default;
};

// 8- or 16-bit images with 1 (grey), 3 (BGR) or 4 (BGRA) channels. Throws std::invalid_argument
// for any other image.
std::vector<std::uint8_t> encode_png(const cv::Mat& image, const PngOptions& options = {});
// Binary PGM (1 channel) or PPM (3 channels, BGR), 8- or 16-bit (big-endian in the file).
std::vector<std::uint8_t> encode_pnm(const cv::Mat& image);
// 8-bit grey or BGR; quality 1-100. Throws std::invalid_argument for any other image.
std::vector<std::uint8_t> encode_jpeg(const cv::Mat& image, int quality = 95);

struct ImageWriteOptions {
  PngOptions png;
  int jpeg_quality = 95;
};

// Format from the extension: .png, .pgm / .ppm / .pnm, .jpg / .jpeg (any case). Throws
// InputError "<file>: cannot write image (<reason>)" for an unknown extension, an image the
// format cannot hold, or a failed write (the reason is then the system's, e.g. disk full).
void write_image(const std::filesystem::path& file, const cv::Mat& image, const ImageWriteOptions& options = {});

}  // namespace nirslam
