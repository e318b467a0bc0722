#pragma once

// The camera state a GUI reads and the controls it writes, between a camera's producer (the V4L2
// capture thread, the simulator's source) and everyone else: one lock, changes validated at once
// against the state's ranges and queued for the producer, which alone talks to the device and
// applies them before its next frame.

#include <mutex>
#include <optional>
#include <string>

#include "nirslam/capture/camera_controls.hpp"

namespace nirslam {

// Operator changes waiting for the producer.
struct PendingCameraControls {
  std::optional<double> exposure_ms;
  std::optional<double> gain;
  std::optional<bool> auto_exposure;
  std::optional<double> fps;
  std::optional<bool> locked;
  bool any() const { return exposure_ms || gain || auto_exposure || fps || locked; }
};

class CameraControlHub final : public CameraControls {
public:
  explicit CameraControlHub(std::string device) { state_.device = std::move(device); }

  CameraState state() const override;
  // InputError naming the device and the control when a value is out of range or the control is
  // locked or absent. A manual exposure ends auto exposure.
  void set_exposure_ms(double exposure_ms) override;
  void set_gain(double gain) override;
  void set_auto_exposure(bool on) override;
  void set_frame_rate(double fps) override;
  void set_locked(bool locked) override;

  // Producer side.
  PendingCameraControls take_pending();
  template <typename F>
  void update(F&& change) {
    const std::lock_guard lock(mutex_);
    change(state_);
  }
  // Range check for the values a source string asks for, before the producer starts.
  void check(const std::string& field, double value, bool exposure) const;
  // A producer whose rate cannot change (the simulator's): set_frame_rate is refused with `why`.
  void fix_frame_rate(std::string why);

private:
  void check_unlocked(const char* field) const;
  void check_range(const std::string& field, double value, const ControlRange& range, const char* unit) const;

  mutable std::mutex mutex_;
  CameraState state_;
  PendingCameraControls pending_;
  std::string fixed_rate_reason_;
};

}  // namespace nirslam
