#include "nirslam/illumination/sweep_camera_lock.hpp"

#include <algorithm>
#include <utility>

#include <fmt/format.h>

#include "nirslam/common/error.hpp"

namespace nirslam {

namespace {

bool wizard_sweeping(SweepStage stage) { return stage == SweepStage::AwaitingPower || stage == SweepStage::Capturing; }

std::string camera_name(const CameraState& state) { return state.device.empty() ? "the camera" : state.device; }

}  // namespace

SweepCameraLock::Change SweepCameraLock::update(SweepStage stage, const std::shared_ptr<CameraControls>& camera) {
  const std::shared_ptr<CameraControls> previous = camera_.lock();
  if (previous != camera) {
    // Another camera (or none): the old one's sweep lock is given back if it is still there.
    Change change;
    if (held_ && previous) change = release(*previous);
    held_ = seen_locked_ = restore_auto_exposure_ = left_to_operator_ = false;
    last_exposure_ms_.reset();
    next_factor_ = 1.0;
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
    if (state.exposure_in_effect_ms) last_exposure_ms_ = state.exposure_in_effect_ms;
    if (state.gain_in_effect) last_gain_ = *state.gain_in_effect;
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
  const double factor = std::exchange(next_factor_, 1.0);
  if (state.locked) {
    left_to_operator_ = true;
    return {Event::OperatorsLock,
            fmt::format("{}'s exposure and gain are locked already; the power sweep keeps them{}.", camera_name(state),
                        factor > 1.0 ? " (unlock them for the advised exposure)" : "")};
  }
  restore_auto_exposure_ = state.auto_exposure;
  const std::string longer = factor > 1.0 && last_exposure_ms_ ? lengthen(camera, state, factor) : std::string();
  camera.set_locked(true);
  held_ = true;
  seen_locked_ = false;
  return {Event::Locked,
          fmt::format("{}'s exposure and gain locked for the power sweep{}{}.", camera_name(state), longer,
                      restore_auto_exposure_ ? " (auto exposure off until it ends)" : "")};
}

// The exposure, then the gain, for `factor` times the last sweep's; says what it set.
std::string SweepCameraLock::lengthen(CameraControls& camera, const CameraState& state, double factor) const {
  const double wanted_ms = *last_exposure_ms_ * factor;
  const double exposure_ms =
      state.exposure_ms.available ? std::clamp(wanted_ms, state.exposure_ms.minimum, state.exposure_ms.maximum) : wanted_ms;
  double gain = last_gain_;
  if (exposure_ms < wanted_ms && state.gain.available)
    gain = std::clamp(last_gain_ * wanted_ms / exposure_ms, state.gain.minimum, state.gain.maximum);
  try {
    camera.set_exposure_ms(exposure_ms);
    if (gain != last_gain_) camera.set_gain(gain);
  } catch (const InputError& e) {
    return fmt::format(" (the advised exposure could not be set: {})", e.what());
  }
  const double reached = exposure_ms * gain / (*last_exposure_ms_ * last_gain_);
  std::string text = fmt::format(" at {:.3g} ms", exposure_ms);
  if (gain != last_gain_ && state.gain_unity > 0.0) text += fmt::format(", gain {:.2g}x", gain / state.gain_unity);
  text += fmt::format(", {:.1f}x the last sweep's", reached);
  if (reached < 0.95 * factor) text += fmt::format(" (the camera's limit; {:.1f}x was advised)", factor);
  return text;
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
