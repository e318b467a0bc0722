#include "nirslam/odometry/image_pyramid.hpp"

#include <algorithm>

namespace nirslam::odometry {

namespace {

void fill_gradients(PyramidLevel& level) {
  const int w = level.width;
  const int h = level.height;
  level.gradient_sq.assign(static_cast<std::size_t>(w * h), 0.0f);
  // Central differences inside; the one-pixel border keeps zero gradient (never sampled there).
  for (int y = 1; y < h - 1; ++y) {
    for (int x = 1; x < w - 1; ++x) {
      const int i = y * w + x;
      auto& d = level.data[static_cast<std::size_t>(i)];
      d[1] = 0.5f * (level.data[static_cast<std::size_t>(i + 1)][0] - level.data[static_cast<std::size_t>(i - 1)][0]);
      d[2] = 0.5f * (level.data[static_cast<std::size_t>(i + w)][0] - level.data[static_cast<std::size_t>(i - w)][0]);
      level.gradient_sq[static_cast<std::size_t>(i)] = d[1] * d[1] + d[2] * d[2];
    }
  }
}

}  // namespace

ImagePyramid::ImagePyramid(const cv::Mat& image, int levels) {
  levels_.resize(static_cast<std::size_t>(std::max(1, levels)));
  PyramidLevel& base = levels_[0];
  base.width = image.cols;
  base.height = image.rows;
  base.data.assign(static_cast<std::size_t>(base.width * base.height), Eigen::Vector3f::Zero());
  for (int y = 0; y < base.height; ++y) {
    const float* row = image.ptr<float>(y);
    for (int x = 0; x < base.width; ++x) base.data[static_cast<std::size_t>(y * base.width + x)][0] = row[x];
  }
  fill_gradients(base);
  for (std::size_t l = 1; l < levels_.size(); ++l) {
    const PyramidLevel& fine = levels_[l - 1];
    PyramidLevel& coarse = levels_[l];
    coarse.width = fine.width / 2;
    coarse.height = fine.height / 2;
    coarse.data.assign(static_cast<std::size_t>(coarse.width * coarse.height), Eigen::Vector3f::Zero());
    for (int y = 0; y < coarse.height; ++y) {
      for (int x = 0; x < coarse.width; ++x) {
        const int i = 2 * y * fine.width + 2 * x;
        coarse.data[static_cast<std::size_t>(y * coarse.width + x)][0] =
            0.25f * (fine.data[static_cast<std::size_t>(i)][0] + fine.data[static_cast<std::size_t>(i + 1)][0] +
                     fine.data[static_cast<std::size_t>(i + fine.width)][0] +
                     fine.data[static_cast<std::size_t>(i + fine.width + 1)][0]);
      }
    }
    fill_gradients(coarse);
  }
}

std::vector<LevelCamera> make_level_cameras(const LevelCamera& base, int levels) {
  std::vector<LevelCamera> cameras{base};
  for (int l = 1; l < levels; ++l) cameras.push_back(cameras.back().down());
  return cameras;
}

int usable_levels(int width, int height, int wanted, int min_coarsest_width) {
  int levels = 1;
  while (levels < wanted && (width >> levels) >= min_coarsest_width && (height >> levels) >= 16) ++levels;
  return levels;
}

}  // namespace nirslam::odometry
