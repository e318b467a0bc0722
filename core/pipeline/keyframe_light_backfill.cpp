#include "nirslam/pipeline/keyframe_light_backfill.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "nirslam/photometric/photometric_tracker.hpp"

namespace nirslam {

void KeyframeLightBackfill::add_keyframe(std::int64_t frame_index, double power_w,
                                         std::vector<std::int64_t> tracks_without_distance) {
  if (tracks_without_distance.empty()) return;
  Pending pending;
  pending.frame_index = frame_index;
  pending.power_w = power_w;
  pending.tracks = std::move(tracks_without_distance);
  pending_.push_back(std::move(pending));
  while (static_cast<int>(pending_.size()) > options_.max_pending_keyframes) pending_.pop_front();
}

void KeyframeLightBackfill::place_keyframe(std::int64_t frame_index, const std::optional<SE3>& T_world_cam, int segment) {
  const auto keyframe =
      std::find_if(pending_.begin(), pending_.end(), [&](const Pending& p) { return p.frame_index == frame_index; });
  if (keyframe == pending_.end()) return;
  if (!T_world_cam) {
    pending_.erase(keyframe);
    return;
  }
  keyframe->T_cam_world = T_world_cam->inverse();
  keyframe->segment = segment;
}

std::size_t KeyframeLightBackfill::pending_tracks() const {
  std::size_t n = 0;
  for (const Pending& p : pending_) n += p.tracks.size();
  return n;
}

std::vector<KeyframeIllumination> KeyframeLightBackfill::resolve(int segment, const VectorOfTrack& point_world,
                                                                 std::span<const TrackObservation> live_tracks,
                                                                 const Eigen::Vector3d& light_offset_cam,
                                                                 const VectorOfTrack& normal_world) {
  std::vector<KeyframeIllumination> out;
  std::unordered_set<std::int64_t> live;
  live.reserve(live_tracks.size());
  for (const TrackObservation& t : live_tracks) live.insert(t.id);
  for (Pending& keyframe : pending_) {
    if (!keyframe.T_cam_world || keyframe.segment != segment) {
      if (keyframe.T_cam_world) keyframe.tracks.clear();  // another world frame and scale
      continue;
    }
    const Eigen::Vector3d light_world = keyframe.T_cam_world->inverse() * light_offset_cam;
    KeyframeIllumination found{keyframe.frame_index, {}};
    std::erase_if(keyframe.tracks, [&](std::int64_t track_id) {
      const std::optional<Eigen::Vector3d> point = point_world(track_id);
      std::optional<Eigen::Vector3d> normal;
      if (point && normal_world) normal = normal_world(track_id);
      if (!point || (normal_world && !normal)) return !live.contains(track_id);
      if (!((*keyframe.T_cam_world * *point).z() > 0.0)) return true;
      const Eigen::Vector3d to_lamp = light_world - *point;
      const double distance = to_lamp.norm();
      double value = log_illumination(keyframe.power_w, distance);
      if (normal) {
        const double cosine = normal->dot(to_lamp) / distance;
        value = cosine >= options_.min_cosine ? log_illumination(keyframe.power_w, distance, std::min(cosine, 1.0)) : std::nan("");
      }
      if (std::isfinite(value)) found.values.push_back(TrackIllumination{track_id, value});
      return true;
    });
    if (!found.values.empty()) out.push_back(std::move(found));
  }
  std::erase_if(pending_, [](const Pending& p) { return p.T_cam_world && p.tracks.empty(); });
  return out;
}

}  // namespace nirslam
