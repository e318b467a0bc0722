#pragma once

// Image pyramid with gradients for direct alignment. Each level stores (I, dI/dx, dI/dy) per
// pixel, interleaved, so one bilinear lookup fetches all three (as DSO's dIp).

#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace nirslam::odometry {

// Pinhole intrinsics of one pyramid level. Pixel centres stay at integer coordinates on every
// level, so c_l = (c_0 + 0.5) / 2^l - 0.5.
struct LevelCamera {
  double fx = 1.0, fy = 1.0, cx = 0.0, cy = 0.0;
  int width = 0, height = 0;

  LevelCamera down() const {
    return {fx * 0.5, fy * 0.5, (cx + 0.5) * 0.5 - 0.5, (cy + 0.5) * 0.5 - 0.5, width / 2, height / 2};
  }
  Eigen::Vector2d project(const Eigen::Vector3d& p) const {
    return {fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy};
  }
  // The ray through a pixel, z = 1.
  Eigen::Vector3d unproject(const Eigen::Vector2d& pixel) const {
    return {(pixel.x() - cx) / fx, (pixel.y() - cy) / fy, 1.0};
  }
  bool inside(double u, double v, double border) const {
    return u >= border && v >= border && u <= width - 1 - border && v <= height - 1 - border;
  }
};

struct PyramidLevel {
  int width = 0;
  int height = 0;
  std::vector<Eigen::Vector3f> data;  // (I, gx, gy), row-major
  std::vector<float> gradient_sq;     // gx^2 + gy^2

  const Eigen::Vector3f& at(int x, int y) const { return data[static_cast<std::size_t>(y * width + x)]; }
  // Bilinear (I, gx, gy); the caller keeps (u, v) within [0, w-1) x [0, h-1).
  Eigen::Vector3f interpolate(float u, float v) const {
    const int x = static_cast<int>(u);
    const int y = static_cast<int>(v);
    const float dx = u - static_cast<float>(x);
    const float dy = v - static_cast<float>(y);
    const Eigen::Vector3f* p = data.data() + y * width + x;
    return (1.0f - dy) * ((1.0f - dx) * p[0] + dx * p[1]) + dy * ((1.0f - dx) * p[width] + dx * p[width + 1]);
  }
  float interpolate_intensity(float u, float v) const {
    const int x = static_cast<int>(u);
    const int y = static_cast<int>(v);
    const float dx = u - static_cast<float>(x);
    const float dy = v - static_cast<float>(y);
    const Eigen::Vector3f* p = data.data() + y * width + x;
    return (1.0f - dy) * ((1.0f - dx) * p[0][0] + dx * p[1][0]) +
           dy * ((1.0f - dx) * p[width][0] + dx * p[width + 1][0]);
  }
};

class ImagePyramid {
public:
  // `image` is CV_32FC1. Level l has size floor(w / 2^l) x floor(h / 2^l).
  ImagePyramid(const cv::Mat& image, int levels);

  int levels() const { return static_cast<int>(levels_.size()); }
  const PyramidLevel& level(int l) const { return levels_[static_cast<std::size_t>(l)]; }

private:
  std::vector<PyramidLevel> levels_;
};

// Level cameras for `levels` levels, level 0 = `base`.
std::vector<LevelCamera> make_level_cameras(const LevelCamera& base, int levels);

// How many levels fit: the coarsest level is at least `min_coarsest_width` wide.
int usable_levels(int width, int height, int wanted, int min_coarsest_width);

}  // namespace nirslam::odometry
