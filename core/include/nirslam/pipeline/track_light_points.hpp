#pragma once
// The lamp's distance to a tracked patch from a surface point held per track (issue 8): the
// first time a track is asked for, its point is placed on the pixel's ray at the distance the
// caller gives (the odometry's points near it, LightDistanceMap, or the track's own
// triangulation, TrackLightDistances), in the world frame of the odometry's pose; from then on
// the distance is that point's from the lamp in each frame's pose.
//
// What the calibration uses is a track's distance RATIO between frames. Looked up afresh every
// frame, the neighbours' distance changes with the odometry's window (points come and go, their
// depths move), which reads as brightness change: on the simulated co-lit scenes the ratio
// along a track was off by 0.05-0.07 in log (median) that way, 0.007-0.021 with the point held
// (README "Illuminator correction", session 30). A held point's own depth error d_err enters a
// ratio only through the camera's motion, by about d_err t / d^2 for a travel t towards it.
// Units are the odometry's (monocular scale cancels in the ratio).

#include <cstdint>
#include <functional>
#include <optional>

#include <Eigen/Core>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/geometry/se3.hpp"
#include "nirslam/pipeline/held_per_track.hpp"

namespace nirslam {

struct TrackLightPointsOptions {
  // A track not asked for this many frames is forgotten (the front end never reuses an id).
  int forget_after_frames = 5;
};

class TrackLightPoints {
public:
  explicit TrackLightPoints(const CameraModel& camera, TrackLightPointsOptions options = {});

  // Starts a frame placed at T_world_cam by the odometry (its predicted pose). A new segment
  // (a new world frame and scale) starts over.
  void begin_frame(const SE3& T_world_cam, int segment);
  void clear();

  // Distance from the lamp at light_offset_cam to the track's held point in the current frame.
  // A track without one gets it placed on the ray through `pixel` (the frame's own, distorted,
  // coordinates) at `first_light_distance()`, which is asked only then. std::nullopt where there
  // is no distance to place it with, the pixel does not unproject, or the point is behind the camera.
  std::optional<double> light_distance(std::int64_t track_id, const Eigen::Vector2d& pixel,
                                       const Eigen::Vector3d& light_offset_cam,
                                       const std::function<std::optional<double>()>& first_light_distance);
  // The same for a track that has a point, without placing one; std::nullopt otherwise.
  std::optional<double> held_light_distance(std::int64_t track_id, const Eigen::Vector3d& light_offset_cam) const;

  // The track's held point (the odometry's world frame); std::nullopt before it has one.
  std::optional<Eigen::Vector3d> point_world(std::int64_t track_id) const {
    const Eigen::Vector3d* held = points_world_.find(track_id);
    return held ? std::optional<Eigen::Vector3d>(*held) : std::nullopt;
  }

  std::size_t tracks() const { return points_world_.size(); }

private:
  std::optional<double> light_distance_from(const Eigen::Vector3d& point_world, const Eigen::Vector3d& light_offset_cam) const;

  const CameraModel& camera_;
  HeldPerTrack<Eigen::Vector3d> points_world_;
  SE3 T_world_cam_;
  SE3 T_cam_world_;
};

}  // namespace nirslam
