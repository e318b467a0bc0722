#include "nirslam/eval/trajectory_error.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace nirslam {

ErrorStatistics summarize_errors(std::vector<double> values) {
  ErrorStatistics s;
  s.count = values.size();
  if (values.empty()) return s;
  double sum = 0.0, sum_sq = 0.0;
  s.min = s.max = values.front();
  for (const double v : values) {
    sum += v;
    sum_sq += v * v;
    s.min = std::min(s.min, v);
    s.max = std::max(s.max, v);
  }
  const double n = static_cast<double>(values.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double deviation_sq = 0.0;
  for (const double v : values) deviation_sq += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(deviation_sq / n);
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  s.median = values[mid];
  if (values.size() % 2 == 0) {
    const double below = *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid));
    s.median = 0.5 * (s.median + below);
  }
  return s;
}

std::vector<double> position_errors(const std::vector<Eigen::Vector3d>& estimate,
                                    const std::vector<Eigen::Vector3d>& ground_truth) {
  if (estimate.size() != ground_truth.size())
    throw std::invalid_argument("position_errors: " + std::to_string(estimate.size()) + " estimated and " +
                                std::to_string(ground_truth.size()) + " ground-truth positions");
  std::vector<double> errors(estimate.size());
  for (std::size_t i = 0; i < estimate.size(); ++i) errors[i] = (estimate[i] - ground_truth[i]).norm();
  return errors;
}

std::vector<double> path_length(const std::vector<Eigen::Vector3d>& positions) {
  std::vector<double> length(positions.size(), 0.0);
  for (std::size_t i = 1; i < positions.size(); ++i)
    length[i] = length[i - 1] + (positions[i] - positions[i - 1]).norm();
  return length;
}

namespace {

constexpr double kDegreesPerRadian = 180.0 / std::numbers::pi;

// The error of the motion from pose i to pose j: E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j).
struct MotionError {
  double translation_m;
  double rotation_deg;
};

MotionError motion_error(const std::vector<SE3>& estimate, const std::vector<SE3>& ground_truth, std::size_t i,
                         std::size_t j, bool with_rotation) {
  if (!with_rotation) {
    const Eigen::Vector3d est_motion = estimate[j].translation() - estimate[i].translation();
    const Eigen::Vector3d gt_motion = ground_truth[j].translation() - ground_truth[i].translation();
    return {(est_motion - gt_motion).norm(), 0.0};
  }
  const SE3 est_motion = estimate[i].inverse() * estimate[j];
  const SE3 gt_motion = ground_truth[i].inverse() * ground_truth[j];
  const SE3 error = gt_motion.inverse() * est_motion;
  // The angle from the quaternion: |w| = cos(angle / 2), robust near 0 and pi.
  const Eigen::Quaterniond& q = error.unit_quaternion();
  const double angle = 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
  return {error.translation().norm(), angle * kDegreesPerRadian};
}

void check_lengths(const std::vector<SE3>& estimate, const std::vector<SE3>& ground_truth) {
  if (estimate.size() != ground_truth.size())
    throw std::invalid_argument("relative error: " + std::to_string(estimate.size()) + " estimated and " +
                                std::to_string(ground_truth.size()) + " ground-truth poses");
}

}  // namespace

RelativeError relative_error_per_frame(const std::vector<SE3>& estimate, const std::vector<SE3>& ground_truth,
                                       std::size_t delta_frames, bool with_rotation) {
  check_lengths(estimate, ground_truth);
  if (delta_frames == 0) throw std::invalid_argument("relative_error_per_frame: delta must be at least 1");
  RelativeError result;
  result.kind = RelativeError::Kind::PerFrame;
  result.delta = static_cast<double>(delta_frames);
  result.has_rotation = with_rotation;
  std::vector<double> translation, rotation;
  for (std::size_t i = 0; i + delta_frames < estimate.size(); ++i) {
    const MotionError e = motion_error(estimate, ground_truth, i, i + delta_frames, with_rotation);
    translation.push_back(e.translation_m);
    if (with_rotation) rotation.push_back(e.rotation_deg);
  }
  result.translation_m = summarize_errors(std::move(translation));
  result.rotation_deg = summarize_errors(std::move(rotation));
  return result;
}

RelativeError relative_error_per_distance(const std::vector<SE3>& estimate, const std::vector<SE3>& ground_truth,
                                          double distance_m, bool with_rotation) {
  check_lengths(estimate, ground_truth);
  if (!(distance_m > 0.0) || !std::isfinite(distance_m))
    throw std::invalid_argument("relative_error_per_distance: distance must be a positive number of metres");
  RelativeError result;
  result.kind = RelativeError::Kind::PerDistance;
  result.delta = distance_m;
  result.has_rotation = with_rotation;

  std::vector<Eigen::Vector3d> gt_positions;
  gt_positions.reserve(ground_truth.size());
  for (const SE3& T : ground_truth) gt_positions.push_back(T.translation());
  const std::vector<double> travelled = path_length(gt_positions);
  // Summed steps carry round-off: a segment of 10 x 0.1 m counts as 1 m.
  const double reach = distance_m * (1.0 - 1e-9);

  std::vector<double> translation, rotation, translation_percent, rotation_per_m;
  std::size_t j = 0;
  for (std::size_t i = 0; i < ground_truth.size(); ++i) {
    j = std::max(j, i + 1);
    while (j < ground_truth.size() && travelled[j] - travelled[i] < reach) ++j;
    if (j >= ground_truth.size()) break;  // no later start reaches further
    const double length = travelled[j] - travelled[i];
    const MotionError e = motion_error(estimate, ground_truth, i, j, with_rotation);
    translation.push_back(e.translation_m);
    translation_percent.push_back(100.0 * e.translation_m / length);
    if (with_rotation) {
      rotation.push_back(e.rotation_deg);
      rotation_per_m.push_back(e.rotation_deg / length);
    }
  }
  result.translation_m = summarize_errors(std::move(translation));
  result.translation_percent = summarize_errors(std::move(translation_percent));
  result.rotation_deg = summarize_errors(std::move(rotation));
  result.rotation_deg_per_m = summarize_errors(std::move(rotation_per_m));
  return result;
}

}  // namespace nirslam
