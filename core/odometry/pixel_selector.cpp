#include "nirslam/odometry/pixel_selector.hpp"

#include <algorithm>
#include <cmath>

namespace nirslam::odometry {

namespace {

// Squared-gradient threshold per region: (median |grad| + margin)^2, from a 64-bin histogram of
// |grad| (grey levels per pixel, clipped at 63), as DSO's makeHists.
std::vector<float> region_thresholds(const PyramidLevel& level, int region, double margin, int& regions_x,
                                     int& regions_y) {
  regions_x = (level.width + region - 1) / region;
  regions_y = (level.height + region - 1) / region;
  std::vector<float> thresholds(static_cast<std::size_t>(regions_x * regions_y));
  std::vector<int> histogram(64);
  for (int ry = 0; ry < regions_y; ++ry) {
    for (int rx = 0; rx < regions_x; ++rx) {
      std::fill(histogram.begin(), histogram.end(), 0);
      int count = 0;
      for (int y = std::max(1, ry * region); y < std::min(level.height - 1, (ry + 1) * region); ++y) {
        for (int x = std::max(1, rx * region); x < std::min(level.width - 1, (rx + 1) * region); ++x) {
          const float g = std::sqrt(level.gradient_sq[static_cast<std::size_t>(y * level.width + x)]);
          ++histogram[static_cast<std::size_t>(std::min(63, static_cast<int>(g)))];
          ++count;
        }
      }
      int median = 0;
      for (int accumulated = 0; median < 63; ++median) {
        accumulated += histogram[static_cast<std::size_t>(median)];
        if (2 * accumulated >= count) break;
      }
      const double t = median + 0.5 + margin;
      thresholds[static_cast<std::size_t>(ry * regions_x + rx)] = static_cast<float>(t * t);
    }
  }
  return thresholds;
}

std::vector<Eigen::Vector2i> select_with_cell(const PyramidLevel& level, const std::vector<float>& thresholds,
                                              int regions_x, int region, int cell, int border) {
  std::vector<Eigen::Vector2i> selected;
  for (int y0 = border; y0 < level.height - border; y0 += cell) {
    for (int x0 = border; x0 < level.width - border; x0 += cell) {
      float best = 0.0f;
      Eigen::Vector2i best_pixel(-1, -1);
      float best_weak = 0.0f;
      Eigen::Vector2i weak_pixel(-1, -1);
      for (int y = y0; y < std::min(y0 + cell, level.height - border); ++y) {
        for (int x = x0; x < std::min(x0 + cell, level.width - border); ++x) {
          const float g = level.gradient_sq[static_cast<std::size_t>(y * level.width + x)];
          const float t = thresholds[static_cast<std::size_t>((y / region) * regions_x + x / region)];
          if (g > t && g > best) {
            best = g;
            best_pixel = {x, y};
          } else if (g > 0.5625f * t && g > best_weak) {  // 0.75^2: the second tier of DSO
            best_weak = g;
            weak_pixel = {x, y};
          }
        }
      }
      if (best_pixel.x() >= 0) {
        selected.push_back(best_pixel);
      } else if (weak_pixel.x() >= 0 && ((x0 / cell + y0 / cell) & 1) == 0) {
        selected.push_back(weak_pixel);  // half the weak cells: fills bland regions sparsely
      }
    }
  }
  return selected;
}

}  // namespace

std::vector<Eigen::Vector2i> select_pixels(const PyramidLevel& level, const PixelSelectorOptions& options) {
  int regions_x = 0;
  int regions_y = 0;
  const auto thresholds = region_thresholds(level, options.region_size, options.min_gradient, regions_x, regions_y);
  const double area = static_cast<double>(level.width - 2 * options.border) * (level.height - 2 * options.border);
  double cell = std::sqrt(area / std::max(1, options.wanted));
  std::vector<Eigen::Vector2i> selected;
  for (int attempt = 0; attempt < 4; ++attempt) {
    const int c = std::max(1, static_cast<int>(std::lround(cell)));
    selected = select_with_cell(level, thresholds, regions_x, options.region_size, c, options.border);
    const double ratio = static_cast<double>(selected.size()) / std::max(1, options.wanted);
    if (ratio > 0.8 && ratio < 1.25) break;
    if (c == 1 && ratio < 1.0) break;
    // Fewer cells qualify than exist: shrink the cell by the square root of the shortfall.
    cell = std::max(1.0, cell * std::sqrt(std::max(0.05, ratio)));
  }
  return selected;
}

}  // namespace nirslam::odometry
