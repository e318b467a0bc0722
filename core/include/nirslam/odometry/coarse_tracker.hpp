#pragma once

// Coarse-to-fine direct image alignment of a frame to the newest keyframe (DSO's CoarseTracker):
// the window's points projected into the keyframe give a sparse inverse depth map, averaged
// down the pyramid; each level refines SE(3) + affine brightness (a, b) of the new frame by
// Levenberg-Marquardt with Huber weights, starting at the coarsest level.

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/common/helper_thread.hpp"
#include "nirslam/odometry/image_pyramid.hpp"
#include "nirslam/odometry/photometric_residual.hpp"

namespace nirslam::odometry {

struct CoarseTrackerOptions {
  double huber_threshold = 9.0;
  double gradient_weight_c = 50.0;
  double outlier_threshold = 20.0;  // |r| above: outlier (doubled on a level with too few inliers)
  int iterations_per_level = 8;
  double affine_a_prior = 1.0;      // energy weights pulling the frame's a, b to 0
  double affine_b_prior = 1e-2;
  LampGeometry lamp;  // the co-located lamp's distance factor (photometric_residual.hpp), when enabled
};

struct ReferencePoint {
  Eigen::Vector2d pixel;  // in the keyframe, level 0
  double inverse_depth = 1.0;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // surface normal in the keyframe (lamp), zero: unknown
};

struct TrackingEstimate {
  SE3 T_frame_ref;
  double affine_a = 0.0;
  double affine_b = 0.0;
  double rms = 0.0;               // Huber-weighted rms of the finest level's inliers, grey levels
  int residual_count = 0;         // inliers at the finest level
  double inlier_fraction = 0.0;   // of the points that project into the frame
  double flow_translation = 0.0;  // rms pixel shift of the reference points by t alone
  double flow_full = 0.0;         // by (R, t)
  bool valid = false;
  std::vector<double> level_rms;  // per level, finest first
};

class CoarseTracker {
public:
  CoarseTracker(std::vector<LevelCamera> cameras, const CoarseTrackerOptions& options);

  // The reference keyframe, its affine brightness and exposure, and the points' pixels and
  // inverse depths in it.
  void set_reference(std::shared_ptr<const ImagePyramid> pyramid, double affine_a, double affine_b,
                     double exposure, const std::vector<ReferencePoint>& points);
  bool has_reference() const { return reference_ != nullptr; }
  int reference_point_count() const { return static_cast<int>(levels_.empty() ? 0 : levels_[0].size()); }

  // Aligns `frame`, starting at the guess. With `abort_rms` > 0, gives up (valid = false) as
  // soon as a level's rms exceeds abort_rms times `abort_reference` of that level (for trying
  // several motion hypotheses cheaply, as DSO does).
  TrackingEstimate track(const ImagePyramid& frame, double exposure, const SE3& T_frame_ref_guess, double a_guess,
                         double b_guess, const std::vector<double>* abort_reference = nullptr,
                         double abort_factor = 1.5) const;

  // The lamp's geometry from the next alignment on (an online beam estimate).
  void set_lamp(const LampGeometry& lamp) { options_.lamp = lamp; }
  void set_affine_priors(double a_weight, double b_weight) {
    options_.affine_a_prior = a_weight;
    options_.affine_b_prior = b_weight;
  }

private:
  struct LevelPoint {
    float u, v;  // level pixel
    float inverse_depth;
    float reference_intensity;
    Eigen::Vector3f normal;  // zero: unknown
  };
  // Energy and normal equations of one level at (T, a, b); returns inlier count.
  int accumulate(int level, const ImagePyramid& frame, double exposure, const SE3& T, double a, double b,
                 double cutoff, Matrix8d* H, Vector8d* g, double& energy, int& projected) const;

  std::vector<LevelCamera> cameras_;
  CoarseTrackerOptions options_;
  std::shared_ptr<const ImagePyramid> reference_;
  double reference_a_ = 0.0;
  double reference_b_ = 0.0;
  double reference_exposure_ = 1.0;
  std::vector<std::vector<LevelPoint>> levels_;
  // One point's part of accumulate(), computed on two threads and summed in point order.
  struct PointTerm {
    int kind = 0;  // 0: not projected, 1: projected without a residual, 2: outlier, 3: inlier
    double energy = 0.0;  // of an inlier
    double W = 0.0;
    double r = 0.0;
    Vector8d J = Vector8d::Zero();
  };
  mutable std::vector<PointTerm> terms_;  // scratch of accumulate(): track() is not reentrant
  std::shared_ptr<HelperThread> helper_ = std::make_shared<HelperThread>();
};

}  // namespace nirslam::odometry
