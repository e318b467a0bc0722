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
  std::uint64_t sum = 0;          // of the (clamped) codes
  std::uint64_t sum_squares = 0;  // of the (clamped) codes; < 2^64 up to 2^31 pixels of 16 bits
};

// One pass for the histogram and the clipping counts. Four interleaved partial histograms break
// the store-to-load dependency between neighbouring pixels of equal value (2-3x faster on natural
// images). Clipping is counted on codes, not bins: with more than 8 bits the top bin holds many
// codes that are not saturated. Codes above the declared range (corrupt data) count as saturated.
Scan scan_8bit(const cv::Mat& image) {
  std::array<std::array<std::uint32_t, 256>, 4> partial{};
  Scan scan;
  for (int y = 0; y < image.rows; ++y) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(y);
    int x = 0;
    for (; x + 4 <= image.cols; x += 4) {
      ++partial[0][row[x]];
      ++partial[1][row[x + 1]];
      ++partial[2][row[x + 2]];
      ++partial[3][row[x + 3]];
    }
    for (; x < image.cols; ++x) ++partial[0][row[x]];
    // Flush per row so the 32-bit partial counts cannot overflow on huge images.
    for (int bin = 0; bin < 256; ++bin) {
      scan.histogram[bin] += partial[0][bin] + partial[1][bin] + partial[2][bin] + partial[3][bin];
    }
    partial = {};
  }
  scan.saturated = scan.histogram[255];
  scan.black = scan.histogram[0];
  // With 8 bits a bin is a code: the moments follow from the 256 counts.
  for (std::uint64_t code = 0; code < 256; ++code) {
    scan.sum += code * scan.histogram[code];
    scan.sum_squares += code * code * scan.histogram[code];
  }
  return scan;
}

Scan scan_16bit(const cv::Mat& image, int bit_depth) {
  Scan scan;
  const std::uint32_t top_code = (1u << bit_depth) - 1u;
  const int shift = bit_depth - 8;
  std::array<std::array<std::uint32_t, 256>, 4> partial{};
  const auto clamp_code = [top_code](std::uint32_t value) { return value >= top_code ? top_code : value; };
  for (int y = 0; y < image.rows; ++y) {
    const std::uint16_t* row = image.ptr<std::uint16_t>(y);
    std::uint64_t row_sum = 0;
    std::uint64_t row_squares = 0;
    for (int x = 0; x < image.cols; ++x) {
      const std::uint32_t value = clamp_code(row[x]);
      ++partial[x & 3][value >> shift];
      scan.saturated += value == top_code;
      scan.black += value == 0;
      row_sum += value;
      row_squares += static_cast<std::uint64_t>(value) * value;
    }
    scan.sum += row_sum;
    scan.sum_squares += row_squares;
    for (int bin = 0; bin < 256; ++bin) {
      scan.histogram[bin] += partial[0][bin] + partial[1][bin] + partial[2][bin] + partial[3][bin];
    }
    partial = {};
  }
  return scan;
}

void check_quality_input(const cv::Mat& image, int bit_depth) {
  if (image.empty()) throw std::invalid_argument("image quality: empty image");
  if (image.type() == CV_8UC1 && bit_depth == 8) return;
  if (image.type() == CV_16UC1 && bit_depth >= 9 && bit_depth <= 16) return;
  throw std::invalid_argument("image quality: expected CV_8UC1 with bit depth 8 or CV_16UC1 with "
                              "bit depth 9..16, got type " + std::to_string(image.type()) +
                              " with bit depth " + std::to_string(bit_depth));
}

Scan scan(const cv::Mat& image, int bit_depth) {
  check_quality_input(image, bit_depth);
  return image.depth() == CV_8U ? scan_8bit(image) : scan_16bit(image, bit_depth);
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

ImageQuality measure_quality(const cv::Mat& image, int bit_depth, GreyHistogram* histogram) {
  const Scan pixels = scan(image, bit_depth);
  if (histogram) *histogram = pixels.histogram;
  const double count = static_cast<double>(image.total());
  ImageQuality quality;
  quality.entropy_bits = entropy_bits(pixels.histogram);
  quality.saturated_fraction = static_cast<double>(pixels.saturated) / count;
  quality.black_fraction = static_cast<double>(pixels.black) / count;
  const double full_scale = static_cast<double>((1u << bit_depth) - 1u);
  const double mean_code = static_cast<double>(pixels.sum) / count;
  // E[x^2] - E[x]^2 in double: the cancellation error is ~1e-16 of the squared mean, far below a code.
  const double variance = std::max(0.0, static_cast<double>(pixels.sum_squares) / count - mean_code * mean_code);
  quality.mean = mean_code / full_scale;
  quality.rms_contrast = std::sqrt(variance) / full_scale;
  return quality;
}

}  // namespace nirslam
