#pragma once
// Frames and folders shared by the session tests (tests/core/test_session_*.cpp).

#include <cmath>
#include <filesystem>
#include <string>

#include <opencv2/core.hpp>

#include "nirslam/image/frame.hpp"

namespace nirslam::testing {

// A fresh, empty folder under the system's temp folder (removed first if it exists).
inline std::filesystem::path fresh_session_dir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("nirslam_session_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// Frame `index` of a deterministic sequence: noise (PNG cannot shrink it much, so disk use is
// realistic) seeded by the index, 8-bit or 12-bit in a 16-bit container, with every metadata field set.
inline Frame synthetic_frame(std::int64_t index, int bit_depth = 8, int width = 64, int height = 48) {
  Frame frame;
  cv::RNG rng(static_cast<std::uint64_t>(1000 + index));
  frame.image = cv::Mat(height, width, bit_depth > 8 ? CV_16UC1 : CV_8UC1);
  rng.fill(frame.image, cv::RNG::UNIFORM, 0, bit_depth > 8 ? (1 << bit_depth) : 256);
  frame.bit_depth = bit_depth;
  frame.index = index;
  frame.timestamp_s = 100.0 + 0.05 * static_cast<double>(index);
  frame.exposure_ms = 5.0 + 0.25 * static_cast<double>(index);
  frame.gain = 2.0;
  frame.illuminator_power_w = 40.0 + static_cast<double>(index % 3);
  frame.T_world_cam_truth = SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * static_cast<double>(index), Eigen::Vector3d::UnitY())),
                                Eigen::Vector3d(0.1 * static_cast<double>(index), 0.0, 0.3 * std::sin(0.3 * static_cast<double>(index))));
  frame.name = "synthetic " + std::to_string(index);
  return frame;
}

inline bool same_pixels(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

}  // namespace nirslam::testing
