#pragma once
// The lamp's distance to a patch the photometric calibration tracks, from the patch's own track
// (issue 8): every frame the odometry has a pose for adds the track's viewing ray in the world
// frame, and once the rays cross at a wide enough angle the surface point is where they meet
// (least squares over all rays, the midpoint method). LightDistanceMap gives a patch the distance
// of the odometry's points near it instead, which at a depth edge or on a surface seen at a
// grazing angle (a tunnel wall, a floor ahead) mixes surfaces; the track's own point does not.
//
// What the calibration uses is a track's distance ratio between frames, each frame's distance
// computed with the point as known then: a point that still moves (little parallax) would put
// its later correction into the ratio. So no distance is given until the rays span
// min_parallax_deg, by which time the point is known to about ray noise / sin(parallax) in depth.
// Units are the odometry's (monocular scale cancels in the ratio).

#include <cstdint>
#include <optional>
#include <span>
#include <unordered_map>

#include <Eigen/Core>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/geometry/se3.hpp"

namespace nirslam {

struct TrackObservation;

struct TrackLightDistancesOptions {
  // The widest angle between two of a track's rays (its first and any later one) before the
  // point counts as known.
  double min_parallax_deg = 3.0;
  int min_rays = 3;
  // The rms distance of the point from the track's rays, as an angle in pixels at the camera's
  // focal length, above which the track is taken to have slid (KLT drift, an occlusion edge,
  // something moving) and gives no distance.
  double max_ray_error_px = 1.5;
};

class TrackLightDistances {
public:
  explicit TrackLightDistances(const CameraModel& camera, TrackLightDistancesOptions options = {});

  // The tracks of a frame the odometry has placed at T_world_cam (segment: the odometry's; a new
  // one starts over, its world frame and scale are new). Tracks not in this frame are forgotten
  // (the front end's track ids are never reused).
  void add_frame(std::span<const TrackObservation> tracks, const SE3& T_world_cam, int segment);
  void clear();

  // The triangulated point of a track (world frame); std::nullopt while its rays do not span the
  // parallax, or disagree.
  std::optional<Eigen::Vector3d> point_world(std::int64_t track_id) const;
  // Distance from the lamp (at light_offset_cam in a camera at T_world_cam, e.g. the predicted
  // pose of the frame about to be calibrated) to the track's point; std::nullopt where the point
  // is not known or lies behind that camera.
  std::optional<double> light_distance(std::int64_t track_id, const SE3& T_world_cam,
                                       const Eigen::Vector3d& light_offset_cam) const;

  std::size_t tracks() const { return tracks_.size(); }
  std::size_t triangulated() const;

private:
  // Normal equations of the midpoint method: sum (I - u u^T) x = sum (I - u u^T) c over rays
  // (origin c, unit direction u), the constant sum c^T (I - u u^T) c for the residual, and the
  // sum of the origins for the range the residual is read at.
  struct Rays {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    double origin_term = 0.0;
    Eigen::Vector3d origin_sum = Eigen::Vector3d::Zero();
    Eigen::Vector3d first_direction = Eigen::Vector3d::Zero();
    double min_cos_to_first = 1.0;  // the widest angle to the first ray, as a cosine
    int count = 0;
    std::int64_t last_seen = 0;     // frames added (this object's own count)
    std::optional<Eigen::Vector3d> point;  // when the rays determine it
  };
  void solve(Rays& rays) const;

  const CameraModel& camera_;
  TrackLightDistancesOptions options_;
  double min_parallax_cos_;
  double max_ray_error_rad_;
  std::unordered_map<std::int64_t, Rays> tracks_;
  std::int64_t frames_ = 0;
  int segment_ = -1;
};

}  // namespace nirslam
