#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <opencv2/core/mat.hpp>

#include "nirslam/geometry/se3.hpp"

namespace nirslam {

// One grey image as it came from a source, with what the source knows about how it was taken.
// `image` is CV_8UC1 or CV_16UC1. A 16-bit container may hold fewer significant bits (Y10, Y12):
// `bit_depth` says how many, so quality measures bin and clip against the real range.
struct Frame {
  cv::Mat image;
  int bit_depth = 8;                          // 8 for CV_8UC1; 9..16 for CV_16UC1
  double timestamp_s = 0.0;
  std::int64_t index = 0;                     // position in the source, from 0
  std::optional<double> exposure_ms;          // when the source reports it
  std::optional<double> gain;                 // linear analogue gain, when known
  std::optional<double> illuminator_power_w;  // NIR illuminator power, when known
  std::string name;                           // file name or device frame id, for messages
  // Ground truth, when the source knows it (the simulator): camera-to-world pose at the frame's
  // timestamp. Never used by the pipeline, only for overlays and evaluation.
  std::optional<SE3> T_world_cam_truth;

  int width() const { return image.cols; }
  int height() const { return image.rows; }
  std::uint32_t max_value() const { return (1u << bit_depth) - 1u; }
};

// Throws std::invalid_argument naming `what` if the frame is not a well-formed grey image.
void validate_frame(const Frame& frame, const std::string& what);

}  // namespace nirslam
