#pragma once

// Whether a tracked patch holds a depth edge, from the simulator's depth map (z per pixel).

#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/photometric/photometric_tracker.hpp"

namespace nirslam::test_depth_edge {

// Whether the patch around pixel (x, y), with two pixels to spare, holds a depth step. A plane's
// inverse depth is affine in the pinhole image, so its second difference along a row or a column
// is zero however slanted the plane; an occluding contour or a crease makes it jump. Steps of
// more than 1 % of the inverse depth count. Such a patch holds two surfaces that move apart in
// the image and sit at two distances from the lamp.
inline bool patch_on_depth_edge(const cv::Mat& depth, int x, int y) {
  constexpr int kReach = kPatchRadius + 2;
  const auto inverse = [&](int u, int v) {
    const float z = depth.at<float>(v, u);
    return z > 0.0f ? 1.0f / z : 0.0f;
  };
  for (int v = std::max(y - kReach, 1); v <= std::min(y + kReach, depth.rows - 2); ++v)
    for (int u = std::max(x - kReach, 1); u <= std::min(x + kReach, depth.cols - 2); ++u) {
      const float w = inverse(u, v);
      if (!(w > 0.0f)) return true;  // a ray into the void beside a surface
      if (std::abs(inverse(u - 1, v) - 2.0f * w + inverse(u + 1, v)) > 0.01f * w ||
          std::abs(inverse(u, v - 1) - 2.0f * w + inverse(u, v + 1)) > 0.01f * w)
        return true;
    }
  return false;
}

// Where patch_on_depth_edge is false, as a mask (CV_8UC1, 255 off the edges): the pixels whose
// inverse depth has a second difference over 1 % of it (or no surface), dilated by the patch and
// its two pixels to spare.
inline cv::Mat off_depth_edges(const cv::Mat& depth) {
  cv::Mat inverse;
  cv::divide(1.0, depth, inverse, CV_32F);
  inverse.setTo(0.0f, depth <= 0.0f);
  cv::Mat dxx, dyy;
  const cv::Mat second = (cv::Mat_<float>(1, 3) << 1.0f, -2.0f, 1.0f);
  cv::filter2D(inverse, dxx, CV_32F, second, cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
  cv::filter2D(inverse, dyy, CV_32F, second.t(), cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
  const cv::Mat step = (cv::abs(dxx) > 0.01 * inverse) | (cv::abs(dyy) > 0.01 * inverse) | (inverse <= 0.0f);
  cv::Mat near_step;
  constexpr int kReach = kPatchRadius + 2;
  cv::dilate(step, near_step, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * kReach + 1, 2 * kReach + 1)));
  return near_step == 0;
}

}  // namespace nirslam::test_depth_edge
