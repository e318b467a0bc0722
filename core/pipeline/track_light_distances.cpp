#include "nirslam/pipeline/track_light_distances.hpp"

#include <cmath>
#include <numbers>

#include <Eigen/LU>

#include "nirslam/photometric/photometric_tracker.hpp"

namespace nirslam {

TrackLightDistances::TrackLightDistances(const CameraModel& camera, TrackLightDistancesOptions options)
    : camera_(camera),
      options_(options),
      min_parallax_cos_(std::cos(options.min_parallax_deg * std::numbers::pi / 180.0)),
      max_ray_error_rad_(options.max_ray_error_px / camera.fx()) {}

void TrackLightDistances::clear() {
  tracks_.clear();
  segment_ = -1;
}

void TrackLightDistances::add_frame(std::span<const TrackObservation> tracks, const SE3& T_world_cam, int segment) {
  if (segment != segment_) {
    tracks_.clear();
    segment_ = segment;
  }
  ++frames_;
  const Eigen::Matrix3d R_world_cam = T_world_cam.rotation_matrix();
  const Eigen::Vector3d& centre = T_world_cam.translation();
  for (const TrackObservation& track : tracks) {
    const auto ray_cam = camera_.unproject(track.position);
    if (!ray_cam) continue;
    const Eigen::Vector3d u = (R_world_cam * *ray_cam).normalized();
    Rays& rays = tracks_[track.id];
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - u * u.transpose();
    rays.A += P;
    const Eigen::Vector3d Pc = P * centre;
    rays.b += Pc;
    rays.origin_term += centre.dot(Pc);
    rays.origin_sum += centre;
    if (rays.count == 0) rays.first_direction = u;
    rays.min_cos_to_first = std::min(rays.min_cos_to_first, u.dot(rays.first_direction));
    ++rays.count;
    rays.last_seen = frames_;
    solve(rays);
  }
  // Tracks the front end lost do not come back under the same id.
  std::erase_if(tracks_, [this](const auto& entry) { return entry.second.last_seen != frames_; });
}

void TrackLightDistances::solve(Rays& rays) const {
  rays.point.reset();
  if (rays.count < options_.min_rays || rays.min_cos_to_first > min_parallax_cos_) return;
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(rays.A);
  if (!lu.isInvertible()) return;
  const Eigen::Vector3d x = lu.solve(rays.b);
  if (!x.allFinite()) return;
  // The rms distance of x from the rays (x^T A x - 2 b^T x + the origin term is their sum of
  // squares) as an angle seen from the rays' mean origin.
  const double squared = std::max(0.0, x.dot(rays.A * x) - 2.0 * rays.b.dot(x) + rays.origin_term);
  const double range = (x - rays.origin_sum / rays.count).norm();
  if (!(range > 0.0) || std::sqrt(squared / rays.count) > max_ray_error_rad_ * range) return;
  rays.point = x;
}

std::optional<Eigen::Vector3d> TrackLightDistances::point_world(std::int64_t track_id) const {
  const auto it = tracks_.find(track_id);
  if (it == tracks_.end()) return std::nullopt;
  return it->second.point;
}

std::optional<double> TrackLightDistances::light_distance(std::int64_t track_id, const SE3& T_world_cam,
                                                          const Eigen::Vector3d& light_offset_cam) const {
  const auto point = point_world(track_id);
  if (!point) return std::nullopt;
  const Eigen::Vector3d p_cam = T_world_cam.inverse() * *point;
  if (!(p_cam.z() > 0.0)) return std::nullopt;
  return (p_cam - light_offset_cam).norm();
}

std::size_t TrackLightDistances::triangulated() const {
  std::size_t n = 0;
  for (const auto& entry : tracks_) n += entry.second.point.has_value();
  return n;
}

}  // namespace nirslam
