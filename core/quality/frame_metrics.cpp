#include "nirslam/quality/frame_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <opencv2/features2d.hpp>

namespace nirslam {
namespace {

void check_gradient_energy_input(const cv::Mat& image, int bit_depth) {
  if (image.empty()) throw std::invalid_argument("gradient energy: empty image");
  if (image.type() == CV_8UC1 && bit_depth == 8) return;
  if (image.type() == CV_16UC1 && bit_depth >= 9 && bit_depth <= 16) return;
  throw std::invalid_argument("gradient energy: expected CV_8UC1 with bit depth 8 or CV_16UC1 with bit depth "
                              "9..16, got type " + std::to_string(image.type()) + " with bit depth " +
                              std::to_string(bit_depth));
}

// Sum of squared forward differences over the (rows - 1) x (cols - 1) pixels with both neighbours.
// 8 bits: a term is at most 2 * 255^2 = 130050, so 32-bit partial sums are safe for 33025 pixels;
// rows are summed in blocks of 16384 pixels into 64 bits. The loop vectorises (widen, subtract,
// multiply-add).
std::uint64_t squared_differences_8bit(const cv::Mat& image) {
  constexpr int kBlock = 16384;
  std::uint64_t total = 0;
  for (int y = 0; y + 1 < image.rows; ++y) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(y);
    const std::uint8_t* below = image.ptr<std::uint8_t>(y + 1);
    for (int x0 = 0; x0 + 1 < image.cols; x0 += kBlock) {
      const int x1 = std::min(image.cols - 1, x0 + kBlock);
      std::uint32_t partial = 0;
      for (int x = x0; x < x1; ++x) {
        const int centre = row[x];
        const int dx = row[x + 1] - centre;
        const int dy = below[x] - centre;
        partial += static_cast<std::uint32_t>(dx * dx + dy * dy);
      }
      total += partial;
    }
  }
  return total;
}

// 16 bits: a term reaches 2 * 65535^2 > 2^32, so rows sum in 64 bits. Codes above the declared
// range count as the top code, as in measure_quality.
std::uint64_t squared_differences_16bit(const cv::Mat& image, int bit_depth) {
  const std::int64_t top = (std::int64_t{1} << bit_depth) - 1;
  std::uint64_t total = 0;
  for (int y = 0; y + 1 < image.rows; ++y) {
    const std::uint16_t* row = image.ptr<std::uint16_t>(y);
    const std::uint16_t* below = image.ptr<std::uint16_t>(y + 1);
    std::uint64_t partial = 0;
    for (int x = 0; x + 1 < image.cols; ++x) {
      const std::int64_t centre = std::min<std::int64_t>(row[x], top);
      const std::int64_t dx = std::min<std::int64_t>(row[x + 1], top) - centre;
      const std::int64_t dy = std::min<std::int64_t>(below[x], top) - centre;
      partial += static_cast<std::uint64_t>(dx * dx + dy * dy);
    }
    total += partial;
  }
  return total;
}

// The top eight significant bits of a deeper frame, as the histogram bins them.
void top_eight_bits(const cv::Mat& image, int bit_depth, cv::Mat& out) {
  out.create(image.rows, image.cols, CV_8UC1);
  const int shift = bit_depth - 8;
  const std::uint32_t top = (1u << bit_depth) - 1u;
  for (int y = 0; y < image.rows; ++y) {
    const std::uint16_t* in = image.ptr<std::uint16_t>(y);
    std::uint8_t* row = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < image.cols; ++x)
      row[x] = static_cast<std::uint8_t>(std::min<std::uint32_t>(in[x], top) >> shift);
  }
}

// Counts points into `grid` (its cols and rows set), reusing its storage.
void count_into(std::span<const cv::KeyPoint> points, cv::Size size, FeatureGrid& grid) {
  grid.counts.assign(static_cast<std::size_t>(grid.cols) * static_cast<std::size_t>(grid.rows), 0u);
  const double to_col = static_cast<double>(grid.cols) / size.width;
  const double to_row = static_cast<double>(grid.rows) / size.height;
  for (const cv::KeyPoint& p : points) {
    const int c = std::clamp(static_cast<int>(std::floor(p.pt.x * to_col)), 0, grid.cols - 1);
    const int r = std::clamp(static_cast<int>(std::floor(p.pt.y * to_row)), 0, grid.rows - 1);
    ++grid.counts[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid.cols) + static_cast<std::size_t>(c)];
  }
}

}  // namespace

double gradient_energy(const cv::Mat& image, int bit_depth) {
  check_gradient_energy_input(image, bit_depth);
  if (image.rows < 2 || image.cols < 2) return 0.0;
  const std::uint64_t sum =
      image.depth() == CV_8U ? squared_differences_8bit(image) : squared_differences_16bit(image, bit_depth);
  const double full_scale = static_cast<double>((1u << bit_depth) - 1u);
  const double pixels = static_cast<double>(image.rows - 1) * static_cast<double>(image.cols - 1);
  return static_cast<double>(sum) / (pixels * full_scale * full_scale);
}

FeatureGrid count_in_grid(std::span<const cv::KeyPoint> points, cv::Size size, int cols, int rows) {
  if (cols < 1 || rows < 1) throw std::invalid_argument("feature grid: needs at least one cell a side");
  if (size.width < 1 || size.height < 1) throw std::invalid_argument("feature grid: empty image size");
  FeatureGrid grid;
  grid.cols = cols;
  grid.rows = rows;
  count_into(points, size, grid);
  return grid;
}

ImageStructure summarise_grid(const FeatureGrid& grid) {
  ImageStructure s;
  s.cells = grid.cols * grid.rows;
  std::uint64_t total = 0;
  for (const auto n : grid.counts) {
    total += n;
    s.occupied_cells += n > 0 ? 1 : 0;
  }
  s.feature_count = static_cast<int>(total);
  s.coverage = s.cells > 0 ? static_cast<double>(s.occupied_cells) / s.cells : 0.0;
  if (total > 0 && s.cells > 1) {
    const double inv_total = 1.0 / static_cast<double>(total);
    double entropy = 0.0;
    for (const auto n : grid.counts) {
      if (n == 0) continue;
      const double p = static_cast<double>(n) * inv_total;
      entropy -= p * std::log(p);
    }
    s.evenness = std::clamp(entropy / std::log(static_cast<double>(s.cells)), 0.0, 1.0);
  }
  return s;
}

QualityMeter::QualityMeter(QualityOptions options) : options_(options) {
  if (options_.fast_threshold < 1 || options_.fast_threshold > 254)
    throw std::invalid_argument("quality meter: FAST threshold must be within 1..254 grey levels");
  if (options_.grid_cols < 1 || options_.grid_rows < 1 || options_.grid_cols > 256 || options_.grid_rows > 256)
    throw std::invalid_argument("quality meter: the coverage grid must have 1..256 cells a side");
}

FrameMetrics QualityMeter::measure(const cv::Mat& image, int bit_depth, GreyHistogram* histogram, FeatureGrid* grid) {
  FrameMetrics metrics;
  metrics.quality = measure_quality(image, bit_depth, histogram);  // validates the image
  metrics.structure.gradient_energy = gradient_energy(image, bit_depth);

  const cv::Mat* grey8 = &image;
  if (image.depth() != CV_8U) {
    top_eight_bits(image, bit_depth, grey8_);
    grey8 = &grey8_;
  }
  corners_.clear();
  cv::FAST(*grey8, corners_, options_.fast_threshold, options_.fast_nonmax_suppression);

  // Counted into the kept grid: no allocation after the first frame.
  grid_.cols = options_.grid_cols;
  grid_.rows = options_.grid_rows;
  count_into(corners_, image.size(), grid_);
  const double energy = metrics.structure.gradient_energy;
  metrics.structure = summarise_grid(grid_);
  metrics.structure.gradient_energy = energy;
  if (grid != nullptr) *grid = grid_;
  return metrics;
}

}  // namespace nirslam
