#pragma once

// A camera's own auto exposure follows the lamp during a power sweep and cancels what the sweep
// is meant to show (the images hardly change, the response is seen over a sliver of its range).
// The lock holds a camera's exposure and gain from the wizard's start to its end and then gives
// back the auto exposure it took. A lock the operator set stays the operator's, and an operator
// who unlocks the camera while the sweep runs is not overruled.
//
// The GUI calls update() on every frame with the wizard's stage and the camera in use; the camera
// controls are thread-safe, so this never waits on the capture thread.

#include <memory>
#include <optional>
#include <string>

#include "nirslam/capture/camera_controls.hpp"
#include "nirslam/illumination/sweep_recorder.hpp"

namespace nirslam {

class SweepCameraLock {
public:
  enum class Event {
    None,
    Locked,           // the sweep started: exposure and gain held, auto exposure off
    Released,         // the sweep ended: the lock lifted, auto exposure back on if it was
    OperatorsLock,    // the sweep started on a camera the operator had locked: left as it is
    OperatorUnlocked, // the operator unlocked during the sweep: left to them
    Failed,           // giving the auto exposure back failed (the device refused)
  };
  struct Change {
    Event event = Event::None;
    std::string message;  // for the operator; empty with Event::None
  };

  Change update(SweepStage stage, const std::shared_ptr<CameraControls>& camera);

  // The next sweep starts at `factor` times the exposure x gain the last one was held at (the
  // sweep's advice when its images stopped short of the top): the exposure first, then the gain
  // for what the longest exposure cannot give. Used once, by the next sweep that locks.
  void sweep_again_at(double factor) { next_factor_ = factor; }
  // What the last sweep held the camera at (nothing before one, or after the camera changed).
  std::optional<double> last_sweep_exposure_ms() const { return last_exposure_ms_; }

  // While the lock holds a camera for the sweep, what it holds, short enough for the wizard's
  // line: "held at 12.3 ms, gain 1x until the sweep ends".
  std::optional<std::string> holding() const;

private:
  Change lock(CameraControls& camera);
  std::string lengthen(CameraControls& camera, const CameraState& state, double factor) const;
  Change release(CameraControls& camera);

  std::weak_ptr<CameraControls> camera_;
  bool held_ = false;               // this lock set the camera's lock for the running sweep
  bool seen_locked_ = false;        // the camera's state has shown the lock since it was set
  bool restore_auto_exposure_ = false;
  bool left_to_operator_ = false;   // until the sweep ends, the camera's lock is not touched
  std::optional<double> last_exposure_ms_;
  double last_gain_ = 1.0;          // device units, as CameraState::gain
  double next_factor_ = 1.0;
};

}  // namespace nirslam
