#include "nirslam/eval/association.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <tuple>

#include "nirslam/common/error.hpp"

namespace nirslam {

namespace fs = std::filesystem;

namespace {

fs::path name_of(const Trajectory& trajectory, const char* fallback) {
  return trajectory.source.empty() ? fs::path(fallback) : trajectory.source;
}

std::string seconds(double t) {
  std::array<char, 64> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.6f", t);
  return buffer.data();
}

std::string span_text(double first, double last) { return "[" + seconds(first) + ", " + seconds(last) + "] s"; }

// Round-off allowance for comparing differences of large timestamps (1.4e9 s has 0.24 us steps).
double slack_for(double t) { return 1e-9 + 8.0 * std::numeric_limits<double>::epsilon() * std::abs(t); }

SE3 interpolate_between(const TimedPose& a, const TimedPose& b, double t) {
  const double u = (t - a.timestamp_s) / (b.timestamp_s - a.timestamp_s);
  const Eigen::Vector3d position = (1.0 - u) * a.T_world_cam.translation() + u * b.T_world_cam.translation();
  const Eigen::Quaterniond rotation = a.T_world_cam.unit_quaternion().slerp(u, b.T_world_cam.unit_quaternion());
  return SE3(rotation, position);
}

// Index of the last ground-truth pose at or before t, or -1.
std::ptrdiff_t last_at_or_before(const std::vector<double>& times, double t) {
  const auto it = std::upper_bound(times.begin(), times.end(), t);
  return static_cast<std::ptrdiff_t>(it - times.begin()) - 1;
}

// |t - nearest ground-truth stamp| with its signed dt (t - t_gt).
double nearest_dt(const std::vector<double>& times, double t) {
  const std::ptrdiff_t j = last_at_or_before(times, t);
  double best = std::numeric_limits<double>::infinity();
  if (j >= 0) best = t - times[static_cast<std::size_t>(j)];
  if (j + 1 < static_cast<std::ptrdiff_t>(times.size())) {
    const double after = t - times[static_cast<std::size_t>(j + 1)];
    if (std::abs(after) < std::abs(best)) best = after;
  }
  return best;
}

}  // namespace

std::optional<SE3> interpolate_pose(const Trajectory& trajectory, double t) {
  const std::vector<double> times = trajectory.timestamps();
  if (times.empty() || t < times.front() || t > times.back()) return std::nullopt;
  const std::size_t j = static_cast<std::size_t>(last_at_or_before(times, t));
  if (times[j] == t || j + 1 >= times.size()) return trajectory.poses[j].T_world_cam;
  return interpolate_between(trajectory.poses[j], trajectory.poses[j + 1], t);
}

Association associate(const Trajectory& estimate, const Trajectory& ground_truth, const AssociationOptions& options) {
  if (!(options.max_dt_s >= 0.0) || !std::isfinite(options.max_dt_s))
    throw std::invalid_argument("associate: max_dt_s must be a finite number >= 0");
  if (!std::isfinite(options.time_offset_s)) throw std::invalid_argument("associate: time_offset_s must be finite");
  validate_trajectory(estimate, "estimate");
  validate_trajectory(ground_truth, "ground truth");
  const fs::path est_name = name_of(estimate, "estimate");
  const fs::path gt_name = name_of(ground_truth, "ground truth");

  Association result;
  result.options = options;
  result.estimate_count = estimate.size();
  result.ground_truth_count = ground_truth.size();
  result.position_only = estimate.position_only || ground_truth.position_only;

  std::vector<double> est_times = estimate.timestamps();
  for (double& t : est_times) t += options.time_offset_s;
  const std::vector<double> gt_times = ground_truth.timestamps();
  const double tolerance = options.max_dt_s;

  if (est_times.back() + tolerance + slack_for(est_times.back()) < gt_times.front() ||
      est_times.front() - tolerance - slack_for(est_times.front()) > gt_times.back()) {
    std::string hint;
    const double a = std::abs(est_times.front()), b = std::abs(gt_times.front());
    if (std::max(a, b) > 1e14 && std::min(a, b) < 1e11)  // 1e14 ns is a day; 1e11 s is 3000 years
      hint = " (the magnitudes differ by more than 1e6: one file may hold nanoseconds, the other seconds)";
    else
      hint = " (wrong file, or a clock offset: see the time offset option)";
    throw InputError(est_name, "no overlap in time with the ground truth " + gt_name.string() + ": the estimate spans " +
                                   span_text(est_times.front(), est_times.back()) + ", the ground truth " +
                                   span_text(gt_times.front(), gt_times.back()) + hint);
  }

  if (options.method == AssociationMethod::Nearest) {
    struct Candidate {
      double abs_dt;
      std::size_t i;
      std::size_t j;
      double dt;
    };
    std::vector<Candidate> candidates;
    for (std::size_t i = 0; i < est_times.size(); ++i) {
      const double t = est_times[i];
      const double reach = tolerance + slack_for(t);
      auto it = std::lower_bound(gt_times.begin(), gt_times.end(), t - reach);
      for (; it != gt_times.end() && *it <= t + reach; ++it) {
        const std::size_t j = static_cast<std::size_t>(it - gt_times.begin());
        candidates.push_back({std::abs(t - *it), i, j, t - *it});
      }
    }
    std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
      return std::tie(a.abs_dt, a.i, a.j) < std::tie(b.abs_dt, b.i, b.j);
    });
    std::vector<bool> est_used(est_times.size(), false), gt_used(gt_times.size(), false);
    for (const Candidate& c : candidates) {
      if (est_used[c.i] || gt_used[c.j]) continue;
      est_used[c.i] = gt_used[c.j] = true;
      PosePair pair;
      pair.estimate_index = c.i;
      pair.ground_truth_index = c.j;
      pair.timestamp_s = est_times[c.i];
      pair.dt_s = c.dt;
      pair.T_world_cam_estimate = estimate.poses[c.i].T_world_cam;
      pair.T_world_cam_ground_truth = ground_truth.poses[c.j].T_world_cam;
      result.pairs.push_back(pair);
    }
    std::sort(result.pairs.begin(), result.pairs.end(),
              [](const PosePair& a, const PosePair& b) { return a.estimate_index < b.estimate_index; });
  } else {
    for (std::size_t i = 0; i < est_times.size(); ++i) {
      const double t = est_times[i];
      const double dt = nearest_dt(gt_times, t);
      if (std::abs(dt) > tolerance + slack_for(t)) continue;
      const std::ptrdiff_t j = last_at_or_before(gt_times, t);
      PosePair pair;
      pair.estimate_index = i;
      pair.timestamp_s = t;
      pair.dt_s = dt;
      pair.T_world_cam_estimate = estimate.poses[i].T_world_cam;
      if (j >= 0 && gt_times[static_cast<std::size_t>(j)] == t) {
        pair.ground_truth_index = static_cast<std::size_t>(j);
        pair.T_world_cam_ground_truth = ground_truth.poses[pair.ground_truth_index].T_world_cam;
      } else if (j >= 0 && static_cast<std::size_t>(j) + 1 < gt_times.size() &&
                 gt_times[static_cast<std::size_t>(j) + 1] - gt_times[static_cast<std::size_t>(j)] <=
                     options.max_interpolation_gap_s) {
        pair.ground_truth_index = static_cast<std::size_t>(j);
        pair.T_world_cam_ground_truth = interpolate_between(ground_truth.poses[pair.ground_truth_index],
                                                            ground_truth.poses[pair.ground_truth_index + 1], t);
        pair.interpolated = true;
      } else {
        continue;  // before the first, after the last, or across a gap of the ground truth
      }
      result.pairs.push_back(pair);
    }
  }

  std::vector<bool> matched(est_times.size(), false);
  for (const PosePair& p : result.pairs) {
    matched[p.estimate_index] = true;
    result.max_abs_dt_s = std::max(result.max_abs_dt_s, std::abs(p.dt_s));
  }
  for (std::size_t i = 0; i < est_times.size(); ++i)
    if (!matched[i] && est_times[i] >= gt_times.front() && est_times[i] <= gt_times.back())
      ++result.unmatched_inside_overlap;

  if (result.pairs.empty()) {
    double closest = std::numeric_limits<double>::infinity();
    for (const double t : est_times) closest = std::min(closest, std::abs(nearest_dt(gt_times, t)));
    throw InputError(est_name, "no estimated pose has a ground-truth pose within " + seconds(tolerance) +
                                   " s (the closest is " + seconds(closest) + " s away): check the time units and "
                                   "offset, or widen the tolerance");
  }
  if (result.pairs.size() < options.min_pairs)
    throw InputError(est_name, "only " + std::to_string(result.pairs.size()) +
                                   " pose(s) pair up with the ground truth " + gt_name.string() + " within " +
                                   seconds(tolerance) + " s; at least " + std::to_string(options.min_pairs) +
                                   " are needed");
  return result;
}

}  // namespace nirslam
