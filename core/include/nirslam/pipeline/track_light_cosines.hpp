#pragma once
// cos(theta) of the lamp's light on a patch the photometric calibration tracks (issue 8), with
// ONE surface normal per track, held in the world frame from the first frame that gives one (or
// the mean of the first few fits, TrackLightCosinesOptions::fits_before_hold).
//
// What the calibration uses is a track's ratio cos_i / cos_ref between frames. With the normal n
// held, cos_i = n . (L_i - X) / d_i = h_i / d_i, h_i the lamp's height over the surface's tangent
// plane, so the ratio is (h_i / h_ref) (d_ref / d_i), and an error e in n enters only through
// h_i / h_ref = 1 - n . (L_i - L_ref) / h_ref: to first order e |L_i - L_ref| / h_ref, the lamp's
// travel along the track over its height above the surface. For a wall or floor the rig moves
// along (a tunnel, a garage floor ahead), the grazing case where the cosine matters most, that is
// small. A normal fitted again in every frame (LightGeometry::cosine) instead puts each frame's
// own fitting error into the ratio, divided by cos_ref (0.1-0.2 on the tunnel's walls): measured
// worse (README "Illuminator correction", session 27).

#include <cstdint>
#include <optional>
#include <utility>

#include <Eigen/Core>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/geometry/se3.hpp"
#include "nirslam/pipeline/held_per_track.hpp"

namespace nirslam {

struct TrackLightCosinesOptions {
  // Below this cosine the light grazes the surface so closely that the ratio is not trusted.
  double min_cosine = 0.05;
  // A track not asked for this many frames is forgotten (the front end never reuses an id).
  int forget_after_frames = 5;
  // The normal held once the track has this many fitted normals, their mean (world frame): one
  // fit's tilt from the points' depth noise makes the first cosine too small on average (cos is
  // largest at the true normal) and the ratio along the track too large. Until then the track
  // has no cosine (the calibration's back-fill gives its earlier keyframes one once it is held).
  // Measured with 5 in Table 2's lamp runs (config/bench-lamp-colit-calibration.yaml, 36 runs):
  // co-lit response 2.98 -> 2.76 grey levels, the odometry 0.0168 -> 0.0151 m, the beam
  // exponent the halo factor carries unchanged (README "Illuminator correction", session 37).
  int fits_before_hold = 1;
};

class TrackLightCosines {
public:
  explicit TrackLightCosines(const CameraModel& camera, TrackLightCosinesOptions options = {});

  // Starts a frame placed at T_world_cam by the odometry (its predicted pose). A new segment
  // (a new world frame) starts over.
  void begin_frame(const SE3& T_world_cam, int segment);
  void clear();

  // cos(theta) for the track seen at `pixel` (the frame's own, distorted, coordinates) with its
  // surface point `light_distance` from the lamp at light_offset_cam. `plane_normal_cam` is this
  // frame's fitted normal there (camera axes), taken only when the track has none yet.
  // std::nullopt where the track has no normal, the pixel does not unproject, or the cosine is
  // below min_cosine.
  std::optional<double> cosine(std::int64_t track_id, const Eigen::Vector2d& pixel, double light_distance,
                               const Eigen::Vector3d& light_offset_cam,
                               const std::optional<Eigen::Vector3d>& plane_normal_cam);

  // The cosine from a track's held normal in the current frame, without touching what is held
  // (for probes); std::nullopt where it has none.
  std::optional<double> held_cosine(std::int64_t track_id, const Eigen::Vector2d& pixel, double light_distance,
                                    const Eigen::Vector3d& light_offset_cam) const;

  // The track's held unit normal (world frame); std::nullopt before it has one.
  std::optional<Eigen::Vector3d> normal_world(std::int64_t track_id) const {
    const Eigen::Vector3d* held = normals_world_.find(track_id);
    return held ? std::optional<Eigen::Vector3d>(*held) : std::nullopt;
  }
  // Whether the track has a normal held (cosine() then needs no fitted one).
  bool holds_normal(std::int64_t track_id) const { return normals_world_.contains(track_id); }

  std::size_t tracks() const { return normals_world_.size(); }

private:
  // cos(theta) from a world normal in the current frame, NaN where the pixel does not unproject.
  double cosine_from(const Eigen::Vector3d& normal_world, const Eigen::Vector2d& pixel, double light_distance,
                     const Eigen::Vector3d& light_offset_cam) const;

  const CameraModel& camera_;
  TrackLightCosinesOptions options_;
  HeldPerTrack<Eigen::Vector3d> normals_world_;
  HeldPerTrack<std::pair<Eigen::Vector3d, int>> pending_world_;  // the fits so far: their sum and count
  Eigen::Matrix3d R_world_cam_ = Eigen::Matrix3d::Identity();
};

}  // namespace nirslam
