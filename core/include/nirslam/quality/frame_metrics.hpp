#pragma once

// Every per-frame image metric the advisor and the operator use, beyond the histogram ones of
// image_quality.hpp: sharpness (gradient energy) and corner features with their spread over the
// image. QualityMeter computes all of them for one frame, reusing its buffers between frames, in
// about 1-2 ms for 640x480 on one core (tests/benchmarks/bench_image_quality.cpp).

#include <cstdint>
#include <span>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include "nirslam/image/frame.hpp"
#include "nirslam/quality/image_quality.hpp"

namespace nirslam {

struct QualityOptions {
  // FAST-9 corner threshold in grey levels of 8 bits (ORB's default). Deeper frames are measured on
  // their top eight significant bits, as the histogram bins them, so a threshold means the same
  // contrast at any bit depth. An absolute threshold on purpose: a dim image shows fewer corners.
  int fast_threshold = 20;
  bool fast_nonmax_suppression = true;
  // The grid over which corner coverage and evenness are counted (cells across and down).
  int grid_cols = 16;
  int grid_rows = 12;
};

// Sharpness and corner features of one frame.
struct ImageStructure {
  // Gradient energy: mean over the pixels that have a right and a lower neighbour of
  // (I(x+1,y) - I(x,y))^2 + (I(x,y+1) - I(x,y))^2, with I in fractions of full scale. 0 for a flat
  // image, 1/3 for uniform white noise over the full range. Its square root is the RMS gradient in
  // full scales per pixel.
  double gradient_energy = 0.0;
  int feature_count = 0;   // FAST corners
  int occupied_cells = 0;  // grid cells holding at least one corner
  int cells = 0;           // grid cells in all
  double coverage = 0.0;   // occupied_cells / cells, 0..1
  // Evenness of the spread of corners over ALL cells of the grid: the entropy of the per-cell
  // shares p_c = n_c / N normalised by its maximum, E = -sum_c p_c ln p_c / ln(cells). 1 when every
  // cell holds the same number of corners, 0 when all corners (or none) are in one cell. Unlike
  // coverage it sees that 500 corners in one cell and one in each other cell are not spread.
  double evenness = 0.0;
};

// Per-cell corner counts, row-major (rows x cols), for the UI's coverage map.
struct FeatureGrid {
  int cols = 0;
  int rows = 0;
  std::vector<std::uint32_t> counts{};
};

struct FrameMetrics {
  ImageQuality quality{};
  ImageStructure structure{};
};

// Gradient energy (see ImageStructure) of a CV_8UC1 image of bit depth 8 or a CV_16UC1 image of
// bit depth 9..16. 0 for images narrower or lower than 2 pixels. Throws std::invalid_argument as
// measure_quality does.
double gradient_energy(const cv::Mat& image, int bit_depth);

// Counts points into a cols x rows grid over an image of `size` (cell of a point: floor(x * cols /
// width), clamped to the grid). Throws std::invalid_argument for an empty grid or image size.
FeatureGrid count_in_grid(std::span<const cv::KeyPoint> points, cv::Size size, int cols, int rows);

// Count, occupied cells, coverage and evenness of a grid of counts (gradient_energy is left 0).
ImageStructure summarise_grid(const FeatureGrid& grid);

// Computes FrameMetrics frame after frame. The histogram pass (measure_quality) runs once; the 8-bit
// view that FAST needs, the corner list and the grid are kept between frames, so a stream of
// same-sized frames allocates nothing after the first. Not thread-safe: one meter per thread.
class QualityMeter {
public:
  // Throws std::invalid_argument for a threshold outside 1..254 or a grid outside 1..256 cells a side.
  explicit QualityMeter(QualityOptions options = {});

  // `histogram` and `grid`, when given, receive the 256-bin histogram and the per-cell corner counts.
  FrameMetrics measure(const cv::Mat& image, int bit_depth, GreyHistogram* histogram = nullptr,
                       FeatureGrid* grid = nullptr);
  FrameMetrics measure(const Frame& frame, GreyHistogram* histogram = nullptr, FeatureGrid* grid = nullptr) {
    return measure(frame.image, frame.bit_depth, histogram, grid);
  }

  // The corners found in the last measured frame (pixel coordinates).
  const std::vector<cv::KeyPoint>& corners() const { return corners_; }
  const QualityOptions& options() const { return options_; }

private:
  QualityOptions options_;
  cv::Mat grey8_;  // 16-bit frames as their top eight significant bits
  std::vector<cv::KeyPoint> corners_;
  FeatureGrid grid_;
};

}  // namespace nirslam
