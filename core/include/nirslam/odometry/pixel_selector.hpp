#pragma once

// Gradient-based pixel selection spread over the image (the idea of DSO's PixelSelector): a
// pixel qualifies when its gradient beats its region's median gradient by a margin, and each
// cell of a grid keeps its strongest qualifying pixel. The cell size adapts until about the
// wanted number of pixels is reached, so textured and bland images both give an even spread.

#include <vector>

#include <Eigen/Core>

#include "nirslam/odometry/image_pyramid.hpp"

namespace nirslam::odometry {

struct PixelSelectorOptions {
  int wanted = 2000;
  int region_size = 32;        // for the adaptive threshold
  double min_gradient = 7.0;   // grey levels above the region median
  int border = 4;              // pixels kept clear of the image edge (pattern + interpolation)
};

// Selected pixels of level 0, in row-major cell order.
std::vector<Eigen::Vector2i> select_pixels(const PyramidLevel& level, const PixelSelectorOptions& options);

}  // namespace nirslam::odometry
