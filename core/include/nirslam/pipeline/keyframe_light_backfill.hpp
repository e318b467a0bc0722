#pragma once
// The lamp's distance for the calibration's earlier keyframes (issue 8), once a track has its
// surface point. With the track's own triangulation as the distance source (tracks, held-tracks)
// a patch has no distance until its rays span the parallax, so the keyframes before that carry
// none and the back end leaves those observations out: on the simulated co-lit scenes four fifths
// of them (README "Illuminator correction", session 32). The keyframes' poses are the odometry's
// by then, so the point the track's later distances come from gives the earlier ones as well, in
// the same world frame and scale: the ratio along the track stays of one point.
//
// The pipeline tells it which tracks of a keyframe had no distance, places the keyframe at the
// odometry's pose of that frame, and asks each later frame which of them have a point now. With
// the lamp's cosine in the calibration's factor, a track's held normal gives the keyframe's
// cosine the same way: n . (L_k - X) / |L_k - X|, L_k the lamp at the keyframe's pose, X the point.

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/photometric/illumination_factor.hpp"

namespace nirslam {

struct TrackObservation;

struct KeyframeLightBackfillOptions {
  // Keyframes waiting at most (the oldest goes first); the back end's online window is 40.
  int max_pending_keyframes = 64;
  // With a normal: below this cosine the keyframe's observation stays without a factor (as
  // TrackLightCosinesOptions::min_cosine leaves the frame's own out).
  double min_cosine = 0.05;
};

// Log illumination found for some tracks of the keyframe at frame_index.
struct KeyframeIllumination {
  std::int64_t frame_index = 0;
  std::vector<TrackIllumination> values;
};

class KeyframeLightBackfill {
public:
  explicit KeyframeLightBackfill(KeyframeLightBackfillOptions options = {}) : options_(options) {}

  // A keyframe the calibration made of frame `frame_index` under the lamp's power `power_w`, with
  // the tracks it had no distance for.
  void add_keyframe(std::int64_t frame_index, double power_w, std::vector<std::int64_t> tracks_without_distance);
  // The odometry's pose of that frame, in its segment `segment`; std::nullopt (the frame was not
  // tracked) forgets the keyframe.
  void place_keyframe(std::int64_t frame_index, const std::optional<SE3>& T_world_cam, int segment);

  // A track's point or unit normal in the world frame, std::nullopt while it has none.
  using VectorOfTrack = std::function<std::optional<Eigen::Vector3d>(std::int64_t track_id)>;
  // log(P / d^2) at each placed keyframe's pose for its waiting tracks that have a point now
  // (point_world, in segment `segment`'s world frame) in front of that keyframe's camera, the lamp
  // at light_offset_cam; with normal_world given, log(P cos / d^2), and a track waits for its
  // normal too. Those tracks stop waiting, and so do tracks not in `live_tracks` (the front end
  // never reuses an id: an ended track gets no point); keyframes of another segment are forgotten.
  std::vector<KeyframeIllumination> resolve(int segment, const VectorOfTrack& point_world,
                                            std::span<const TrackObservation> live_tracks,
                                            const Eigen::Vector3d& light_offset_cam,
                                            const VectorOfTrack& normal_world = {});
  void clear() { pending_.clear(); }

  std::size_t pending_keyframes() const { return pending_.size(); }
  std::size_t pending_tracks() const;

private:
  struct Pending {
    std::int64_t frame_index = 0;
    double power_w = 1.0;
    std::optional<SE3> T_cam_world;  // once placed
    int segment = -1;
    std::vector<std::int64_t> tracks;
  };

  KeyframeLightBackfillOptions options_;
  std::deque<Pending> pending_;
};

}  // namespace nirslam
