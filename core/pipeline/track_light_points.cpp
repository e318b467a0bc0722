#include "nirslam/pipeline/track_light_points.hpp"

#include "nirslam/pipeline/light_distance_map.hpp"

namespace nirslam {

TrackLightPoints::TrackLightPoints(const CameraModel& camera, TrackLightPointsOptions options)
    : camera_(camera), options_(options) {}

void TrackLightPoints::clear() {
  points_world_.clear();
  segment_.reset();
}

void TrackLightPoints::begin_frame(const SE3& T_world_cam, int segment) {
  if (segment_ != segment) {
    points_world_.clear();
    segment_ = segment;
  }
  ++frame_;
  T_world_cam_ = T_world_cam;
  T_cam_world_ = T_world_cam.inverse();
  std::erase_if(points_world_, [this](const auto& entry) { return frame_ - entry.second.last_frame > options_.forget_after_frames; });
}

std::optional<double> TrackLightPoints::held_light_distance(std::int64_t track_id, const Eigen::Vector3d& light_offset_cam) const {
  const auto held = points_world_.find(track_id);
  if (held == points_world_.end()) return std::nullopt;
  const Eigen::Vector3d p_cam = T_cam_world_ * held->second.point_world;
  if (!(p_cam.z() > 0.0)) return std::nullopt;
  return (p_cam - light_offset_cam).norm();
}

std::optional<double> TrackLightPoints::light_distance(std::int64_t track_id, const Eigen::Vector2d& pixel,
                                                       const Eigen::Vector3d& light_offset_cam,
                                                       const std::function<std::optional<double>()>& first_light_distance) {
  if (auto held = points_world_.find(track_id); held != points_world_.end()) {
    held->second.last_frame = frame_;
    return held_light_distance(track_id, light_offset_cam);
  }
  const auto ray = camera_.unproject(pixel);
  if (!ray) return std::nullopt;
  const auto distance = first_light_distance();
  if (!distance || !(*distance > 0.0)) return std::nullopt;
  const Eigen::Vector3d p_cam = point_at_light_distance(ray->normalized(), light_offset_cam, *distance);
  if (!(p_cam.z() > 0.0)) return std::nullopt;
  points_world_[track_id] = HeldPoint{T_world_cam_ * p_cam, frame_};
  return distance;
}

}  // namespace nirslam
