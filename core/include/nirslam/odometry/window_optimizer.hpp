#pragma once

// The sliding-window energy of DSO: keyframes (pose, affine a, b) and their hosted points
// (inverse depth), photometric residuals of every point in every other keyframe, optimised by
// Levenberg-Marquardt on the Schur complement over points. Old keyframes are marginalised into
// a Gaussian prior (H_M, b_M) on the remaining keyframes, by Schur complement of their points
// and then of themselves; frames the prior touches keep their Jacobians at their first estimate
// (FEJ), so the prior and the residuals agree on the null space.
//
// Energy convention: E = sum W r^2 (+ priors); H = sum W J J^T, b = sum W J r, step H dx = -b.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/common/helper_thread.hpp"
#include "nirslam/odometry/image_pyramid.hpp"
#include "nirslam/odometry/photometric_residual.hpp"

namespace nirslam::odometry {

struct FrameParameters {
  SE3 T_cam_world;
  double affine_a = 0.0;
  double affine_b = 0.0;
};

struct PointResidual {
  std::int64_t target_id = 0;
  bool inlier = true;      // false: out of view or above the outlier energy at the last linearisation
  double energy = 0.0;     // at the last evaluation
  // Scratch of the current linearisation: coupling to the target frame's 8 parameters.
  Vector8d H_target_point = Vector8d::Zero();
};

struct WindowPoint {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // host, level 0, integer
  std::array<float, kPatternSize> host_intensity{};
  double inverse_depth = 1.0;
  double inverse_depth_prior_weight = 0.0;  // the initialiser's points fix the scale, as in DSO
  double inverse_depth_prior_mean = 1.0;
  // The surface normal in the host frame (unit) for the lamp's cos(theta), from neighbouring
  // points' depths (DirectOdometry), when it could be estimated.
  std::optional<Eigen::Vector3d> normal;
  std::vector<PointResidual> residuals;
  // Scratch of the current linearisation.
  double H_pp = 0.0;
  double b_p = 0.0;
  Vector8d H_host_point = Vector8d::Zero();
  double step = 0.0;
  double backup = 0.0;
};

struct WindowFrame {
  std::int64_t id = 0;  // unique, increasing
  std::shared_ptr<const ImagePyramid> pyramid;
  double exposure = 1.0;
  FrameParameters state;
  FrameParameters linearisation;  // first estimate, once first_estimate_fixed
  bool first_estimate_fixed = false;
  double affine_a_prior_weight = 0.0;
  double affine_b_prior_weight = 0.0;
  double pose_prior_weight = 0.0;  // the gauge: the first keyframe of a segment
  SE3 pose_prior;
  std::vector<WindowPoint> points;
  FrameParameters backup;
};

struct WindowOptions {
  double huber_threshold = 9.0;
  double gradient_weight_c = 50.0;
  double outlier_energy = 12.0 * 12.0;  // per pattern pixel
  double initial_lambda = 1e-4;
  // The co-located lamp's distance factor g (photometric_residual.hpp), when enabled: one g per
  // (point, target), from the centre pixel, serves the whole pattern.
  LampGeometry lamp;
};

struct WindowStatistics {
  double initial_energy = 0.0;
  double final_energy = 0.0;
  int iterations = 0;
  int residuals = 0;
};

class WindowOptimizer {
public:
  WindowOptimizer(const LevelCamera& camera, const WindowOptions& options);
  // The lamp's geometry from the next optimisation on (an online beam estimate); the
  // marginalisation prior keeps the linearisation it was made with.
  void set_lamp(const LampGeometry& lamp) { options_.lamp = lamp; }

  std::vector<WindowFrame>& frames() { return frames_; }
  const std::vector<WindowFrame>& frames() const { return frames_; }
  int index_of(std::int64_t id) const;

  // Appends a keyframe (no points yet); the prior grows by an empty block.
  WindowFrame& add_frame(WindowFrame frame);
  // Gives a point residuals in every other keyframe of the window.
  void connect_to_all(WindowPoint& point, std::int64_t host_id) const;

  // The total energy at the current state (clamped residual energies, priors).
  double energy();
  // Levenberg-Marquardt; keeps the best state.
  WindowStatistics optimize(int iterations);
  // One Gauss-Newton (lambda = 0) or LM step from the current state, not applied: the frame part
  // (8 per frame, in window order). For tests.
  Eigen::VectorXd compute_step(double lambda);

  // Marginalises frame `index`: its points' residuals into the prior (points Schur-complemented
  // out), residuals of other points into it dropped, then the frame itself Schur-complemented
  // out of the prior. Returns the removed frame (points included, for the map).
  WindowFrame marginalize_frame(int index);
  // Refines one point's inverse depth alone, the frames held fixed (for a newly activated
  // point). False when fewer than `min_inliers` residuals fit.
  bool optimize_point(int host_index, WindowPoint& point, int iterations, int min_inliers);
  // Marginalises the points for which `leaving` is true into the prior (Schur complement of each
  // point over its inlier residuals, as DSO does for points that leave the field of view) and
  // removes them; returns them.
  template <typename Predicate>
  std::vector<std::pair<std::int64_t, WindowPoint>> marginalize_points(Predicate leaving) {
    std::vector<std::vector<WindowPoint>> kept(frames_.size());
    std::vector<std::pair<std::int64_t, WindowPoint>> removed;
    for (std::size_t i = 0; i < frames_.size(); ++i) {
      std::vector<WindowPoint> leaving_points;
      for (auto& p : frames_[i].points) (leaving(frames_[i], p) ? leaving_points : kept[i]).push_back(std::move(p));
      frames_[i].points = std::move(leaving_points);
    }
    add_points_to_prior();
    for (std::size_t i = 0; i < frames_.size(); ++i) {
      for (auto& p : frames_[i].points) removed.emplace_back(frames_[i].id, std::move(p));
      frames_[i].points = std::move(kept[i]);
    }
    return removed;
  }

  // Removes points with fewer than `min_inliers` inlier residuals, and with `out_of_newest` also
  // those whose residual in the newest keyframe is out of view or an outlier; returns them.
  std::vector<std::pair<std::int64_t, WindowPoint>> remove_bad_points(int min_inliers, bool out_of_newest = false);

  const Eigen::MatrixXd& prior_hessian() const { return H_prior_; }
  const Eigen::VectorXd& prior_gradient() const { return b_prior_; }
  int point_count() const;
  double last_residual_rms() const { return last_rms_; }

private:
  struct Linearization;
  // One pass over the residuals of the points hosted in `only_hosts` (all when null) at the
  // current state: each residual's clamped energy and inlier flag, the residual rms, and with
  // `lin` the points' Schur blocks and the per-pair blocks. Returns the residual energy plus the
  // points' inverse-depth priors. Shared by energy() and linearize().
  double evaluate_residuals(const std::vector<int>* only_hosts, Linearization* lin);
  // Builds the frame system (H, b) with points Schur-complemented; frames in window order.
  // Returns the energy at the current state (of the hosts included; priors when included).
  double linearize(Eigen::MatrixXd& H, Eigen::VectorXd& b, double lambda, const std::vector<int>* only_hosts,
                   bool include_priors);
  // The first part of linearize(): the frame system before damping and before the points are
  // eliminated (their blocks stay in the points); returns the energy.
  double linearize_frames(Eigen::MatrixXd& H, Eigen::VectorXd& b, const std::vector<int>* only_hosts,
                          bool include_priors);
  // The second part: damps the diagonal by (1 + lambda) and Schur-complements the points of
  // `only_hosts` (all when null) out, in place.
  void reduce(Eigen::MatrixXd& H, Eigen::VectorXd& b, double lambda, const std::vector<int>* only_hosts);
  // Solves the reduced system and back-substitutes each point's step.
  Eigen::VectorXd solve(const Eigen::MatrixXd& H, const Eigen::VectorXd& b, double lambda);
  double frame_prior_energy() const;
  Vector8d prior_delta(const WindowFrame& frame) const;
  // Every point currently in the window, Schur-complemented, into the prior (FEJ fixed first).
  void add_points_to_prior();
  void apply_step(const Eigen::VectorXd& dx, double lambda);
  void backup();
  void restore();

  LevelCamera camera_;
  WindowOptions options_;
  std::vector<WindowFrame> frames_;
  Eigen::MatrixXd H_prior_;  // at the frames' first estimates
  Eigen::VectorXd b_prior_;
  double last_rms_ = 0.0;
  // The points' linearisation at the state backup() saved, for restore() (in window order).
  struct PointScratch {
    double H_pp;
    double b_p;
    Vector8d H_host_point;
  };
  struct ResidualScratch {
    bool inlier;
    double energy;
    Vector8d H_target_point;
  };
  std::vector<PointScratch> point_scratch_;
  std::vector<ResidualScratch> residual_scratch_;
  double rms_backup_ = 0.0;
  // The second thread of the residual passes and the Schur complement; copies share it (its
  // run() serves one caller at a time).
  std::shared_ptr<HelperThread> helper_ = std::make_shared<HelperThread>();
};

}  // namespace nirslam::odometry
