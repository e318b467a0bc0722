#include "nirslam/pipeline/track_light_points.hpp"

#include "nirslam/pipeline/light_distance_map.hpp"

namespace nirslam {

TrackLightPoints::TrackLightPoints(const CameraModel& camera, TrackLightPointsOptions options)
    : camera_(camera), points_world_(options.forget_after_frames) {}

void TrackLightPoints::clear() { points_world_.clear(); }

void TrackLightPoints::begin_frame(const SE3& T_world_cam, int segment) {
  points_world_.begin_frame(segment);
  T_world_cam_ = T_world_cam;
  T_cam_world_ = T_world_cam.inverse();
}

std::optional<double> TrackLightPoints::light_distance_from(const Eigen::Vector3d& point_world,
                                                            const Eigen::Vector3d& light_offset_cam) const {
  const Eigen::Vector3d p_cam = T_cam_world_ * point_world;
  if (!(p_cam.z() > 0.0)) return std::nullopt;
  return (p_cam - light_offset_cam).norm();
}

std::optional<double> TrackLightPoints::held_light_distance(std::int64_t track_id, const Eigen::Vector3d& light_offset_cam) const {
  const Eigen::Vector3d* held = points_world_.find(track_id);
  if (held == nullptr) return std::nullopt;
  return light_distance_from(*held, light_offset_cam);
}

std::optional<double> TrackLightPoints::light_distance(std::int64_t track_id, const Eigen::Vector2d& pixel,
                                                       const Eigen::Vector3d& light_offset_cam,
                                                       const std::function<std::optional<double>()>& first_light_distance) {
  if (const Eigen::Vector3d* held = points_world_.touch(track_id)) return light_distance_from(*held, light_offset_cam);
  const auto ray = camera_.unproject(pixel);
  if (!ray) return std::nullopt;
  const auto distance = first_light_distance();
  if (!distance || !(*distance > 0.0)) return std::nullopt;
  const Eigen::Vector3d p_cam = point_at_light_distance(ray->normalized(), light_offset_cam, *distance);
  if (!(p_cam.z() > 0.0)) return std::nullopt;
  points_world_.hold(track_id, T_world_cam_ * p_cam);
  return distance;
}

}  // namespace nirslam
