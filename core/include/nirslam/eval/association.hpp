#pragma once

// Pairs estimated poses with ground-truth poses by timestamp.
//
// Nearest (default): every candidate pair (estimate i, ground truth j) with |t_i + offset - t_j| <=
// max_dt_s is collected; pairs are then taken greedily by increasing |dt| (ties by index), each
// pose used at most once. This is the rule of the TUM benchmark's associate.py (and evo), so ATE
// figures stay comparable with published ones. With a 200 Hz ground truth the time error of a pair
// is at most half a ground-truth period (2.5 ms); at 1 m/s that is 2.5 mm of position error.
//
// Interpolate: for an estimated pose at t that has a ground-truth stamp within max_dt_s, the ground
// truth is evaluated at t exactly (positions linearly, rotations by SLERP) between the two ground
// truth poses around t, provided they are at most max_interpolation_gap_s apart (never across a
// gap in the ground truth). Use it when the ground truth is dense compared with the motion (motion
// capture at 100-200 Hz): it removes the time-quantisation error above. It is not the default
// because sparse ground truth (a total station at a few Hz) would be interpolated along a chord of
// a curved path, and because results would then differ from the published tools'.

#include <cstddef>
#include <optional>
#include <vector>

#include "nirslam/eval/trajectory.hpp"

namespace nirslam {

enum class AssociationMethod { Nearest, Interpolate };

struct AssociationOptions {
  double max_dt_s = 0.02;                 // tolerance |t_est + offset - t_gt|
  double time_offset_s = 0.0;             // added to every estimated timestamp before matching
  AssociationMethod method = AssociationMethod::Nearest;
  double max_interpolation_gap_s = 0.1;   // Interpolate: widest ground-truth interval to bridge
  std::size_t min_pairs = 3;              // fewer matched pairs is an error (alignment needs 3)
};

struct PosePair {
  std::size_t estimate_index = 0;
  // Nearest: the matched ground-truth pose. Interpolate: the ground-truth pose at or before t.
  std::size_t ground_truth_index = 0;
  double timestamp_s = 0.0;  // the estimate's timestamp (offset applied)
  double dt_s = 0.0;         // t_est + offset - t_gt of the nearest ground-truth stamp
  SE3 T_world_cam_estimate;
  SE3 T_world_cam_ground_truth;  // interpolated when the method says so
  bool interpolated = false;
};

struct Association {
  std::vector<PosePair> pairs;  // in the order of the estimate
  std::size_t estimate_count = 0;
  std::size_t ground_truth_count = 0;
  // Estimated poses inside the ground truth's time span that found no partner (gaps, rates).
  std::size_t unmatched_inside_overlap = 0;
  double max_abs_dt_s = 0.0;
  bool position_only = false;  // either side is position-only
  AssociationOptions options;
};

// Throws InputError naming the estimate's source when either trajectory is empty or invalid, when
// the two do not overlap in time (both time spans are in the message), when no pose pairs up
// within the tolerance, and when fewer than options.min_pairs pairs match.
Association associate(const Trajectory& estimate, const Trajectory& ground_truth,
                      const AssociationOptions& options = {});

// The ground truth at time t (linear / SLERP between the poses around t); std::nullopt outside
// its span. Exposed for tests and for tools that resample.
std::optional<SE3> interpolate_pose(const Trajectory& trajectory, double t);

}  // namespace nirslam
