#pragma once

#include <string>

#include "nirslam/capture/camera_controls.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// The live camera's controls: a state banner (streaming, unplugged, failed, with the message), the
// format and rate, the frames captured and dropped, and the exposure (logarithmic, in ms) and gain
// sliders over the device's own ranges and steps, the auto-exposure toggle, the frame rate and the
// lock that holds exposure and gain for the photometric calibration. It draws from a plain
// CameraState and writes every change through CameraControls (thread-safe, applied by the capture
// thread); a change the controls refuse (out of range, locked) shows in the banner.
class CameraPanel {
public:
  // Draws into the current ImGui window. `controls` may be nullptr: the panel then only shows.
  void draw(const CameraState& state, CameraControls* controls);

  // Geometry of the last draw(), in screen pixels, for the screenshot tests.
  const ScreenRect& banner_rect() const { return banner_; }
  const ScreenRect& exposure_slider_rect() const { return exposure_slider_; }
  const ScreenRect& gain_slider_rect() const { return gain_slider_; }
  const ScreenRect& auto_exposure_rect() const { return auto_exposure_; }
  const ScreenRect& lock_rect() const { return lock_; }
  // The last error the controls threw, shown in the banner until the next change succeeds.
  const std::string& control_error() const { return control_error_; }

  // The banner's colour for a state: green streaming, amber unplugged or reconnecting, red failed
  // (or a refused control), grey otherwise.
  static unsigned banner_colour(const CameraState& state, bool control_error);

private:
  void draw_banner(const CameraState& state);
  void draw_exposure(const CameraState& state, CameraControls* controls);
  void draw_rate(const CameraState& state, CameraControls* controls);
  void draw_counters(const CameraState& state);
  template <typename F>
  void apply(F&& change);

  ScreenRect banner_;
  ScreenRect exposure_slider_;
  ScreenRect gain_slider_;
  ScreenRect auto_exposure_;
  ScreenRect lock_;
  std::string control_error_;
  // The slider values while dragged: the state lags a frame or two behind the operator's hand.
  float exposure_entry_ms_ = -1.0f;
  float gain_entry_ = -1.0f;
};

}  // namespace nirslam::ui
