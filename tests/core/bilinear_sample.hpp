#pragma once

// Bilinear sample of a CV_32F image at a sub-pixel position, clamped at the border: the tests'
// reference for what the estimators read between pixels.

#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>

namespace nirslam {

inline float bilinear(const cv::Mat& m, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double tx = x - x0, ty = y - y0;
  const auto at = [&](int xx, int yy) {
    xx = std::clamp(xx, 0, m.cols - 1);
    yy = std::clamp(yy, 0, m.rows - 1);
    return static_cast<double>(m.at<float>(yy, xx));
  };
  return static_cast<float>((1 - ty) * ((1 - tx) * at(x0, y0) + tx * at(x0 + 1, y0)) +
                            ty * ((1 - tx) * at(x0, y0 + 1) + tx * at(x0 + 1, y0 + 1)));
}

}  // namespace nirslam
