#pragma once

#include <array>
#include <cstdint>

#include <opencv2/core/mat.hpp>

#include "nirslam/image/frame.hpp"

namespace nirslam {

using GreyHistogram = std::array<std::uint64_t, 256>;

// Histogram over 256 bins. 8-bit images bin by value; images with more bits are binned by their top
// eight significant bits (value >> (bit_depth - 8)), so a Y10 image and its 8-bit version agree.
// Values above the declared range (corrupt data) land in the top bin.
GreyHistogram grey_histogram(const cv::Mat& image, int bit_depth);

// Information entropy in bits, the paper's Eq. 2-1: H = -sum_i p_i log2 p_i over the 256 bins.
// 0 for an empty histogram or a constant image; at most 8.
double entropy_bits(const GreyHistogram& histogram);

// What one pass over the pixels tells. Grey values are read as fractions of the full scale
// (code / (2^bit_depth - 1)), so 8-bit and 16-bit frames compare; codes above the declared range
// (corrupt data) count as the top code.
struct ImageQuality {
  double entropy_bits = 0.0;
  double saturated_fraction = 0.0;  // pixels at the top code of the bit depth (or above it)
  double black_fraction = 0.0;      // pixels at code 0
  double mean = 0.0;                // mean grey, fraction of full scale
  double rms_contrast = 0.0;        // standard deviation of the grey values, fraction of full scale
};

// One pass over the pixels; `histogram`, when given, receives the 256-bin histogram the entropy
// was computed from (the UI draws it, so it is not computed twice). For 8-bit images the mean and
// the RMS contrast come from the histogram itself (exact); deeper images sum codes in the same pass.
ImageQuality measure_quality(const cv::Mat& image, int bit_depth, GreyHistogram* histogram = nullptr);
inline ImageQuality measure_quality(const Frame& frame, GreyHistogram* histogram = nullptr) {
  return measure_quality(frame.image, frame.bit_depth, histogram);
}

}  // namespace nirslam
