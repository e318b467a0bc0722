#include "nirslam/illumination/sweep_camera_lock.hpp"

#include <fmt/format.h>

#include "nirslam/common/error.hpp"

namespace nirslam {

namespace {

bool wizard_sweeping(SweepStage stage) { return stage == SweepStage::AwaitingPower || stage == SweepStage::Capturing; }

std::string camera_name(const CameraState& state) { return state.device.empty() ? "the camera" : state.device; }

}  // namespace

const char* to_string(SweepCameraLock::Event event) {
  switch (event) {
    case SweepCameraLock::Event::None: return "none";
    case SweepCameraLock::Event::Locked: return "locked";
    case SweepCameraLock::Event::Released: return "released";
    case SweepCameraLock::Event::OperatorsLock: return "operator's lock";
    case SweepCameraLock::Event::OperatorUnlocked: return "operator unlocked";
    case SweepCameraLock::Event::Failed: return "failed";
  }
  return "unknown";
}

SweepCameraLock::Change SweepCameraLock::update(SweepStage stage, const std::shared_ptr<CameraControls>& camera) {
  const std::shared_ptr<CameraControls> previous = camera_.lock();
  if (previous != camera) {
    // Another camera (or none): the old one's sweep lock is given back if it is still there.
    Change change;
    if (held_ && previous) change = release(*previous);
    held_ = seen_locked_ = restore_auto_exposure_ = left_to_operator_ = false;
    camera_ = camera;
    if (change.event != Event::None) return change;
  }
  if (!camera) return {};

  if (!wizard_sweeping(stage)) {
    left_to_operator_ = false;
    return held_ ? release(*camera) : Change{};
  }
  if (left_to_operator_) return {};
  if (!held_) return lock(*camera);

  const CameraState state = camera->state();
  if (state.locked) {
    seen_locked_ = true;
    return {};
  }
  if (!seen_locked_) return {};  // the capture thread has not applied the lock yet
  held_ = false;
  left_to_operator_ = true;
  return {Event::OperatorUnlocked,
          fmt::format("{} was unlocked during the power sweep: with auto exposure on, the exposure follows the lamp "
                      "and the sweep shows little of the camera's response.",
                      camera_name(state))};
}

SweepCameraLock::Change SweepCameraLock::lock(CameraControls& camera) {
  const CameraState state = camera.state();
  if (state.connection == CameraConnection::Failed || state.connection == CameraConnection::Stopped) return {};
  if (state.locked) {
    left_to_operator_ = true;
    return {Event::OperatorsLock,
            fmt::format("{}'s exposure and gain are locked already; the power sweep keeps them.", camera_name(state))};
  }
  restore_auto_exposure_ = state.auto_exposure;
  camera.set_locked(true);
  held_ = true;
  seen_locked_ = false;
  return {Event::Locked,
          fmt::format("{}'s exposure and gain locked for the power sweep{}.", camera_name(state),
                      restore_auto_exposure_ ? " (auto exposure off until it ends)" : "")};
}

SweepCameraLock::Change SweepCameraLock::release(CameraControls& camera) {
  held_ = false;
  const std::string name = camera_name(camera.state());
  camera.set_locked(false);
  if (!restore_auto_exposure_) return {Event::Released, fmt::format("{}'s exposure and gain unlocked after the power sweep.", name)};
  restore_auto_exposure_ = false;
  try {
    camera.set_auto_exposure(true);
  } catch (const InputError& e) {
    return {Event::Failed, fmt::format("{} unlocked after the power sweep, but its auto exposure could not be turned back "
                                       "on: {}",
                                       name, e.what())};
  }
  return {Event::Released, fmt::format("{} unlocked after the power sweep, auto exposure back on.", name)};
}

std::optional<std::string> SweepCameraLock::holding() const {
  const std::shared_ptr<CameraControls> camera = camera_.lock();
  if (!held_ || !camera) return std::nullopt;
  const CameraState state = camera->state();
  std::string text = "held";
  if (state.exposure_in_effect_ms) text += fmt::format(" at {:.3g} ms", *state.exposure_in_effect_ms);
  if (state.gain_in_effect && state.gain_unity > 0.0) text += fmt::format(", gain {:.2g}x", *state.gain_in_effect / state.gain_unity);
  text += " until the sweep ends";  // whether auto exposure comes back: the notification says
  return text;
}

}  // namespace nirslam
