#pragma once
// The lamp's offset from the camera centre, estimated in the pipeline when the rig's
// configuration does not give it (issue 8): the odometry's recent keyframes are kept as
// irradiance images (the calibrated frame divided by exposure and lamp power), and at each new
// keyframe the window's active points are looked up in every kept keyframe that sees them, with
// their surface normals from planes fitted to neighbouring points (light_distance_map.hpp).
// LightOffsetEstimator does the fit. Units are the odometry's (monocular: its own scale), and a
// new segment (new world frame and scale) starts over.

#include <cstddef>
#include <deque>
#include <optional>
#include <span>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/geometry/se3.hpp"
#include "nirslam/illumination/light_offset_estimator.hpp"
#include "nirslam/pipeline/light_distance_map.hpp"

namespace nirslam {

struct KeyframeLightOffsetOptions {
  std::size_t keyframes = 7;       // kept, as many as the odometry's window
  double blur_sigma_px = 1.5;      // at 640 wide: the points sit on edges, a sharp lookup is noisy
  int min_views = 3;               // keyframes that must see a point
  // The lamp's beam B = cos(alpha)^m. The calibration's halo factor H(x) = V(x) B(x) divides it
  // out by pixel, which is wrong by as much as the offset's own effect (light_offset_estimator.hpp):
  // with m known it is multiplied back per pixel and the estimator models it from the lamp.
  double beam_exponent = 0.0;
  // Only the normals are used here: the distance gate and fit (for the calibration) stay off.
  LightDistanceMapOptions normals{.search_radius_px = 40.0, .min_neighbours = 3, .max_log_spread = 0.0,
                                  .fit_inverse_depth_plane = false, .min_plane_points = 8,
                                  .max_plane_flatness = 0.15, .min_cosine = 0.3};
  LightOffsetEstimatorOptions estimator;
};

class KeyframeLightOffset {
public:
  // `camera`: the pinhole the odometry works in (its keyframe images are in it).
  explicit KeyframeLightOffset(const PinholeCamera& camera, KeyframeLightOffsetOptions options = {});

  // A new keyframe of `segment` at T_world_cam; `corrected` is G(I)/H on the 0..255 scale in the
  // odometry's pinhole, `exposure_times_power` what the brightness scales with. A new segment
  // drops what the old one kept.
  void add_keyframe(int segment, const SE3& T_world_cam, const cv::Mat& corrected, double exposure_times_power);

  // Fits the offset to the points (world frame of the current segment), from `start`.
  LightOffsetEstimate estimate(std::span<const Eigen::Vector3d> points_world, const Eigen::Vector3d& start);

  // A beam exponent learnt later (the halo factor over a known lens vignetting): the keyframes
  // kept so far were stored with the old one, so they are dropped.
  void set_beam_exponent(double beam_exponent);
  double beam_exponent() const { return options_.beam_exponent; }

  std::size_t keyframes() const { return views_.size(); }
  void clear();

private:
  struct View {
    SE3 T_cam_world;
    cv::Mat log_irradiance;  // CV_32FC1, blurred; NaN where there is no light
  };
  const PinholeCamera& camera_;
  KeyframeLightOffsetOptions options_;
  LightDistanceMap normals_;
  std::deque<View> views_;
  int segment_ = -1;
  cv::Mat beam_by_pixel_;  // B at each pixel's angle off the axis (m > 0)
  bool beam_set_ = false;
  std::vector<LampObservation> seen_;
};

}  // namespace nirslam
