#pragma once

// Closed-form alignment of an estimated trajectory to ground truth (Umeyama, "Least-squares
// estimation of transformation parameters between two point patterns", IEEE TPAMI 13(4), 1991):
// the rotation R, translation t and (for Sim(3)) scale s minimising
//   sum_i || gt_i - (s R est_i + t) ||^2
// over matched positions. Monocular odometry has no metric scale: Sim(3) is the measure the
// paper's Table 2 uses; SE(3) suits stereo / metric estimates and shows their scale error.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"

namespace nirslam {

enum class AlignmentMode { None, SE3, Sim3 };

// "none", "se3", "sim3".
std::string to_string(AlignmentMode mode);
std::optional<AlignmentMode> alignment_mode_from_string(const std::string& name);

// x -> scale * rotation * x + translation.
struct Sim3Transform {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double scale = 1.0;

  Eigen::Vector3d apply(const Eigen::Vector3d& point) const { return scale * (rotation * point) + translation; }
  // A pose T_world_cam mapped into the target world: rotation R * R_wc, position apply(t_wc).
  SE3 apply(const SE3& T_world_cam) const;
  Sim3Transform inverse() const;
};

// Why `points` cannot fix a rigid alignment (fewer than 3, all at one place, or on one line:
// rotation about the line is then undetermined), or std::nullopt when they can.
std::optional<std::string> alignment_degeneracy(const std::vector<Eigen::Vector3d>& points);

// Umeyama's closed form mapping `source` onto `target` (same length, paired by index). With
// `with_scale` false the scale is fixed at 1 (SE(3)). Throws std::invalid_argument for different
// lengths or a degenerate configuration (see alignment_degeneracy).
Sim3Transform umeyama_alignment(const std::vector<Eigen::Vector3d>& source,
                                const std::vector<Eigen::Vector3d>& target, bool with_scale);

struct AlignmentResult {
  AlignmentMode mode = AlignmentMode::Sim3;
  Sim3Transform transform;    // estimate world -> ground-truth world (identity for None)
  std::size_t pairs_used = 0; // the first N pairs, or all
  // The Sim(3) scale fitted on the same pairs whatever the mode, so that SE(3) and None still
  // report how far the estimate's scale is off: estimate lengths / true lengths = 1 / sim3_scale.
  // Absent only for mode None on points that cannot fix an alignment.
  std::optional<double> sim3_scale;
  // (1 / sim3_scale - 1) * 100: +10 means the estimate is 10 % too large.
  std::optional<double> scale_error_percent() const;
};

// Aligns on the first `first_n` pairs (0: all; more than there are: all) and reports the fit.
// Throws std::invalid_argument as umeyama_alignment does (first_n of 1 or 2 included), except for
// mode None, which needs no alignment and only reports the scale when it can.
AlignmentResult align_positions(const std::vector<Eigen::Vector3d>& estimate,
                                const std::vector<Eigen::Vector3d>& ground_truth, AlignmentMode mode,
                                std::size_t first_n = 0);

}  // namespace nirslam
