#pragma once
// A value held per photometric track for as long as the track is asked for (TrackLightPoints'
// surface points, TrackLightCosines' normals): kept in the odometry's world frame, so a new
// odometry segment (a new world frame and scale) drops everything, and a track not asked for
// `forget_after_frames` frames is dropped (the front end never reuses an id, so a lost track's
// value would only be memory).

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <utility>

namespace nirslam {

template <typename Value>
class HeldPerTrack {
public:
  explicit HeldPerTrack(int forget_after_frames) : forget_after_frames_(forget_after_frames) {}

  void clear() {
    held_.clear();
    segment_.reset();
  }

  // Starts the next frame of odometry segment `segment`.
  void begin_frame(int segment) {
    if (segment_ != segment) {
      held_.clear();
      segment_ = segment;
    }
    ++frame_;
    std::erase_if(held_, [this](const auto& entry) { return frame_ - entry.second.last_frame > forget_after_frames_; });
  }

  // The track's value, nullptr without one; `touch` also counts the track as asked for this frame.
  const Value* find(std::int64_t track_id) const {
    const auto held = held_.find(track_id);
    return held == held_.end() ? nullptr : &held->second.value;
  }
  const Value* touch(std::int64_t track_id) {
    const auto held = held_.find(track_id);
    if (held == held_.end()) return nullptr;
    held->second.last_frame = frame_;
    return &held->second.value;
  }
  // Holds `value` for the track (asked for this frame).
  const Value& hold(std::int64_t track_id, Value value) {
    return held_.insert_or_assign(track_id, Entry{std::move(value), frame_}).first->second.value;
  }

  bool contains(std::int64_t track_id) const { return held_.contains(track_id); }
  std::size_t size() const { return held_.size(); }

private:
  struct Entry {
    Value value;
    std::int64_t last_frame = 0;
  };

  int forget_after_frames_;
  std::unordered_map<std::int64_t, Entry> held_;
  std::int64_t frame_ = 0;
  std::optional<int> segment_;
};

}  // namespace nirslam
