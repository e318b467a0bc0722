#pragma once
// Where the co-located lamp sits relative to the camera centre, from the images (issue 8): when
// the rig's light offset is not configured, the brightness of surface points seen from several
// poses tells it. A point's irradiance, with exposure, power and the halo factor divided out, is
//
//   E_k = rho_p cos(theta_k) / d_k^2,   d_k = |p_k - L|,  cos(theta_k) = n_k . (L - p_k) / d_k
//
// with p_k the point in camera k's frame, L the lamp in the camera frame and n_k the surface's
// normal (towards the camera) where one is known. In logs: l_k = a_p - 2 log d_k (+ log cos).
// The albedo a_p = log rho_p is a nuisance per point, eliminated in closed form (Schur complement
// of the Gauss-Newton system), so the solve is 3x3 whatever the number of points.
//
// What makes L observable is the same point seen at different distances and directions: moving
// towards a surface tells L's component along the view axis, sideways motion (or points spread
// over the image) its lateral components, weakly (the effect is first order in |L| / d). The
// estimate carries its covariance, and says it is not determined when the data do not fix it
// (a camera that only rotates, points all at one distance); its units are those of the points
// (monocular odometry: its own scale).

#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace nirslam {

struct LampObservation {
  Eigen::Vector3d p_cam = Eigen::Vector3d::Zero();  // the surface point in this camera's frame
  double log_irradiance = 0.0;  // log(G^-1(I) / (V e P)): exposure, power, halo divided out
  // Unit normal of the surface in this camera's frame, facing the camera; adds cos(theta).
  std::optional<Eigen::Vector3d> normal_cam;
};

struct LightOffsetEstimatorOptions {
  int max_iterations = 20;
  double huber_log = 0.05;             // robust threshold on the log-irradiance residual
  int min_observations_per_point = 2;  // fewer: the point says nothing about L
  int min_points = 30;
  // Determined: every axis' standard deviation below this fraction of the median distance from
  // the camera to the points (5 cm beside the lens at 2 m is 0.025).
  double max_sigma_fraction = 0.01;
  // A weak prior pulling L to the camera centre (standard deviation as a fraction of the median
  // distance), so a direction the data do not see stays put instead of wandering.
  double prior_sigma_fraction = 0.5;
  // The residuals' standard deviation is taken as at least this (log units) for the covariance.
  double min_residual_sigma = 0.005;
  // A fit whose residuals' robust sigma (1.4826 x median absolute) stays above this (log units)
  // says the model does not hold (halo or response wrong, depths off): its covariance would
  // flatter it, so it is not used.
  double max_sigma_log = 0.06;
  double max_offset_fraction = 0.5;
  // The beam B = cos(alpha)^m around the optical axis, alpha seen from the lamp: with m > 0 the
  // observations keep the beam (the lens vignetting alone divided out) and the model carries it,
  // because with the lamp off the centre the beam is not a function of the pixel alone (5 cm at
  // 3 m moves alpha by 1 degree, a 2 % brightness change at the beam's flank: as large as the
  // falloff change the offset makes). m = 0: the beam is divided out by pixel (or there is none).
  double beam_exponent = 0.0;    // |L| beyond this fraction of the median distance: rejected
};

struct LightOffsetEstimate {
  Eigen::Vector3d offset_cam = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // from the residuals' robust scale
  double rms_log_before = 0.0;  // robust rms of the residuals at the starting offset
  double rms_log_after = 0.0;
  double robust_sigma_log = 0.0;  // of the residuals after the fit
  double median_distance = 0.0;
  int points = 0;
  int observations = 0;
  int iterations = 0;
  bool determined = false;  // the data fix L well enough to use it
  std::string reason;       // why not, when not

  Eigen::Vector3d sigma() const { return covariance.diagonal().cwiseMax(0.0).cwiseSqrt(); }
};

class LightOffsetEstimator {
public:
  explicit LightOffsetEstimator(LightOffsetEstimatorOptions options = {});

  // One surface point seen in several frames (order does not matter). Points with fewer than
  // min_observations_per_point observations, non-finite values or points behind the camera are
  // left out and counted.
  void add_point(std::span<const LampObservation> observations);
  void clear();
  int points() const { return static_cast<int>(point_start_.size()) - 1; }
  int rejected_points() const { return rejected_points_; }

  // Gauss-Newton from `start` (the configured offset, or the camera centre). Never throws on
  // degenerate data: the estimate says why it is not determined.
  LightOffsetEstimate estimate(const Eigen::Vector3d& start = Eigen::Vector3d::Zero()) const;

  // The model's prediction of l_k - a_p for one observation and its derivative in L (for tests
  // and for the solver): -2 log d (- log d + log(n . (L - p)) with a normal; + m log cos(alpha)
  // with a beam).
  static double log_falloff(const LampObservation& o, const Eigen::Vector3d& light_cam,
                            Eigen::Vector3d* d_light = nullptr, double beam_exponent = 0.0);

private:
  double robust_cost(const Eigen::Vector3d& light, double* rms, double* robust_sigma = nullptr) const;
  // The mean of l_k - f_k(L) over a point's lit observations; std::nullopt with too few of them.
  std::optional<double> mean_albedo(int point, const Eigen::Vector3d& light) const;

  LightOffsetEstimatorOptions options_;
  std::vector<LampObservation> observations_;
  std::vector<int> point_start_{0};  // observations of point i: [point_start_[i], point_start_[i+1])
  int rejected_points_ = 0;
};

}  // namespace nirslam
