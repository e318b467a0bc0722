#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace nirslam {

// A control's range in the units an operator uses (milliseconds for exposure), as the device
// reports it. `available` is false when the device has no such control.
struct ControlRange {
  bool available = false;
  double minimum = 0.0;
  double maximum = 0.0;
  double step = 0.0;
  double default_value = 0.0;
};

enum class CameraConnection {
  Opening,       // opening and negotiating
  Streaming,     // frames are coming
  Unplugged,     // the device went away; the stream ended or waits for it to return
  Reconnecting,  // the node is back and is being reopened
  Stopped,       // the stream ended (end of the source), no error
  Failed,        // could not open or negotiate; `error` says why
};

const char* to_string(CameraConnection connection);

// Everything a camera panel shows: a plain value, copied out under the source's lock.
struct CameraState {
  std::string device;         // "/dev/video0"
  std::string card;           // the product name
  std::string format;         // "Y16 640x480"
  int width = 0;
  int height = 0;
  int bit_depth = 8;
  bool stereo_side_by_side = false;
  double fps = 0.0;
  int buffer_count = 0;
  CameraConnection connection = CameraConnection::Opening;
  std::string message;        // last event for the operator (unplug, reconnect)
  std::string error;          // the last error, empty when none

  ControlRange exposure_ms;   // exposure_absolute converted from 100 us units
  ControlRange gain;          // device units
  ControlRange fps_range;     // slowest and fastest rate at the current size
  std::vector<double> rates_fps;  // the rates the device lists at the current format and size, fastest first
  bool auto_exposure_available = false;
  bool auto_exposure = false;
  bool locked = false;        // exposure and gain held; the operator's sliders are disabled
  std::optional<double> exposure_in_effect_ms;  // what the last frame was taken with
  std::optional<double> gain_in_effect;         // device units, as the gain range
  double gain_unity = 1.0;                      // the device gain a Frame reports as 1x

  std::int64_t frames_captured = 0;
  std::int64_t frames_dropped_by_driver = 0;  // gaps in the driver's sequence numbers
  std::int64_t frames_dropped_by_queue = 0;   // the consumer lagged: oldest queued frame dropped
  double measured_fps = 0.0;
};

// What a GUI or the worker may change on a running camera. Thread-safe: calls validate against the
// device's ranges at once (InputError naming the device and the control) and are applied by the
// capture thread before its next frame; the frames report the values in effect.
class CameraControls {
public:
  virtual ~CameraControls() = default;
  virtual CameraState state() const = 0;
  virtual void set_exposure_ms(double exposure_ms) = 0;
  virtual void set_gain(double gain) = 0;
  virtual void set_auto_exposure(bool on) = 0;
  virtual void set_frame_rate(double fps) = 0;
  // Locked: auto exposure off, exposure and gain held at their values; set_exposure_ms and
  // set_gain then throw (the photometric calibration relies on the values not moving).
  virtual void set_locked(bool locked) = 0;
};

}  // namespace nirslam
