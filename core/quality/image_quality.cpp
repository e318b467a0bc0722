#include "nirslam/quality/image_quality.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace nirslam {
namespace {

struct Scan {
  GreyHistogram histogram{};
  std::uint64_t saturated = 0;
  std::uint64_t black = 0;
};

// One pass for the histogram and the clipping counts. Clipping is counted on codes, not bins: with
// more than 8 bits the top bin holds many codes that are not saturated. Codes above the declared
// range (corrupt data) count as saturated.
template <typename Pixel>
Scan scan_pixels(const cv::Mat& image, int bit_depth) {
  Scan scan;
  const std::uint32_t top_code = (1u << bit_depth) - 1u;
  const int shift = bit_depth - 8;
  for (int y = 0; y < image.rows; ++y) {
    const Pixel* row = image.ptr<Pixel>(y);
    for (int x = 0; x < image.cols; ++x) {
      const std::uint32_t value = row[x] >= top_code ? top_code : row[x];
      ++scan.histogram[value >> shift];
      scan.saturated += value == top_code;
      scan.black += value == 0;
    }
  }
  return scan;
}

void check_grey(const cv::Mat& image, int bit_depth) {
  if (image.empty()) throw std::invalid_argument("image quality: empty image");
  if (image.type() == CV_8UC1 && bit_depth == 8) return;
  if (image.type() == CV_16UC1 && bit_depth >= 9 && bit_depth <= 16) return;
  throw std::invalid_argument("image quality: expected CV_8UC1 with bit depth 8 or CV_16UC1 with "
                              "bit depth 9..16, got type " + std::to_string(image.type()) +
                              " with bit depth " + std::to_string(bit_depth));
}

Scan scan(const cv::Mat& image, int bit_depth) {
  check_grey(image, bit_depth);
  return image.depth() == CV_8U ? scan_pixels<std::uint8_t>(image, bit_depth)
                                : scan_pixels<std::uint16_t>(image, bit_depth);
}

}  // namespace

GreyHistogram grey_histogram(const cv::Mat& image, int bit_depth) {
  return scan(image, bit_depth).histogram;
}

double entropy_bits(const GreyHistogram& histogram) {
  std::uint64_t total = 0;
  for (const auto count : histogram) total += count;
  if (total == 0) return 0.0;
  const double inv_total = 1.0 / static_cast<double>(total);
  double entropy = 0.0;
  for (const auto count : histogram) {
    if (count == 0) continue;
    const double p = static_cast<double>(count) * inv_total;
    entropy -= p * std::log2(p);
  }
  // Summation can leave -0.0 or a hair above 8 for uniform histograms.
  return std::clamp(entropy, 0.0, 8.0);
}

ImageQuality measure_quality(const cv::Mat& image, int bit_depth) {
  const Scan pixels = scan(image, bit_depth);
  const double count = static_cast<double>(image.total());
  ImageQuality quality;
  quality.entropy_bits = entropy_bits(pixels.histogram);
  quality.saturated_fraction = static_cast<double>(pixels.saturated) / count;
  quality.black_fraction = static_cast<double>(pixels.black) / count;
  return quality;
}

}  // namespace nirslam
