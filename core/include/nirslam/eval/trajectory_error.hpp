#pragma once

// Absolute trajectory error (ATE) and relative pose error (RPE) on paired poses.
//
// ATE: per pair, the distance between the aligned estimated position and the ground-truth
// position, in metres; summarised as RMSE, mean, median, std, min and max.
//
// RPE compares motions, not positions: for pairs i < j, E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) with Q the
// ground truth and P the (aligned) estimate. Translation error |t(E)| in metres, rotation error the
// angle of R(E) in degrees. Two ways to choose j:
//   per frame     j = i + delta (consecutive pairs for delta 1): drift per frame;
//   per distance  j = the first pair at least `distance_m` of ground-truth path after i (KITTI's
//                 segment measure, every i a start): translation also as % of the segment's
//                 ground-truth length, rotation also in deg/m.
// Position-only trajectories (rotations unknown): E reduces to the difference of the two
// displacement vectors in the world frame; rotation statistics stay empty (count 0).

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"

namespace nirslam {

struct ErrorStatistics {
  std::size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double std = 0.0;  // population standard deviation about the mean
  double min = 0.0;
  double max = 0.0;
};

// All zeros with count 0 for an empty input.
ErrorStatistics summarize_errors(std::vector<double> values);

// || estimate_i - ground_truth_i || per pair (equal lengths required: std::invalid_argument).
std::vector<double> position_errors(const std::vector<Eigen::Vector3d>& estimate,
                                    const std::vector<Eigen::Vector3d>& ground_truth);

struct RelativeError {
  enum class Kind { PerFrame, PerDistance };
  Kind kind = Kind::PerFrame;
  double delta = 1.0;  // frames (PerFrame) or metres (PerDistance)
  bool has_rotation = true;
  ErrorStatistics translation_m;
  ErrorStatistics rotation_deg;
  // PerDistance only: normalised by the segment's ground-truth path length.
  ErrorStatistics translation_percent;
  ErrorStatistics rotation_deg_per_m;
};

// `with_rotation` false treats the poses as positions only (rotations ignored).
RelativeError relative_error_per_frame(const std::vector<SE3>& estimate, const std::vector<SE3>& ground_truth,
                                       std::size_t delta_frames = 1, bool with_rotation = true);
// No segment (count 0) when the ground-truth path is shorter than distance_m.
RelativeError relative_error_per_distance(const std::vector<SE3>& estimate, const std::vector<SE3>& ground_truth,
                                          double distance_m, bool with_rotation = true);

// Cumulative ground-truth path length at each pose (0 at the first).
std::vector<double> path_length(const std::vector<Eigen::Vector3d>& positions);

}  // namespace nirslam
