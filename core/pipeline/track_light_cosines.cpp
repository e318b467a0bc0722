#include "nirslam/pipeline/track_light_cosines.hpp"

#include "nirslam/pipeline/light_distance_map.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace nirslam {

TrackLightCosines::TrackLightCosines(const CameraModel& camera, TrackLightCosinesOptions options)
    : camera_(camera), options_(options), normals_world_(options.forget_after_frames), pending_world_(options.forget_after_frames) {}

void TrackLightCosines::clear() {
  normals_world_.clear();
  pending_world_.clear();
}

void TrackLightCosines::begin_frame(const SE3& T_world_cam, int segment) {
  normals_world_.begin_frame(segment);
  pending_world_.begin_frame(segment);
  R_world_cam_ = T_world_cam.rotation_matrix();
}

double TrackLightCosines::cosine_from(const Eigen::Vector3d& normal_world, const Eigen::Vector2d& pixel, double light_distance,
                                      const Eigen::Vector3d& light_offset_cam) const {
  const auto ray = camera_.unproject(pixel);
  if (!ray || !(light_distance > 0.0)) return std::nan("");
  const Eigen::Vector3d to_lamp =
      (light_offset_cam - point_at_light_distance(ray->normalized(), light_offset_cam, light_distance)) / light_distance;
  // The held normal faces the lamp as it was first seen; the lamp stays on that side of the surface.
  return (R_world_cam_.transpose() * normal_world).dot(to_lamp);
}

std::optional<double> TrackLightCosines::cosine(std::int64_t track_id, const Eigen::Vector2d& pixel, double light_distance,
                                                const Eigen::Vector3d& light_offset_cam,
                                                const std::optional<Eigen::Vector3d>& plane_normal_cam) {
  const Eigen::Vector3d* held = normals_world_.touch(track_id);
  if (held == nullptr) {
    if (!plane_normal_cam) return std::nullopt;
    Eigen::Vector3d sum = R_world_cam_ * plane_normal_cam->normalized();
    int fits = 1;
    if (const auto* pending = pending_world_.touch(track_id)) {
      sum += pending->first;
      fits += pending->second;
    }
    if (fits < options_.fits_before_hold) {
      pending_world_.hold(track_id, {sum, fits});
      return std::nullopt;
    }
    // Each fitted normal faces the lamp where it was fitted, and the lamp stays on one side of the
    // surface along a track, so the fits agree in sign and their sum is their mean's direction.
    // (One fit is held as it is: normalised again its last bits would move every run's figures.)
    if (!(sum.norm() > 0.0)) return std::nullopt;
    held = &normals_world_.hold(track_id, fits == 1 ? sum : Eigen::Vector3d(sum.normalized()));
  }
  const double c = cosine_from(*held, pixel, light_distance, light_offset_cam);
  if (!(c >= options_.min_cosine)) return std::nullopt;
  return std::min(c, 1.0);
}

std::optional<double> TrackLightCosines::held_cosine(std::int64_t track_id, const Eigen::Vector2d& pixel, double light_distance,
                                                     const Eigen::Vector3d& light_offset_cam) const {
  const Eigen::Vector3d* held = normals_world_.find(track_id);
  if (held == nullptr) return std::nullopt;
  const double c = cosine_from(*held, pixel, light_distance, light_offset_cam);
  if (!std::isfinite(c)) return std::nullopt;
  return c;
}

}  // namespace nirslam
