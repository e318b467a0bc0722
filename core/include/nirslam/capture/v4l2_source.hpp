#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "nirslam/capture/camera_controls.hpp"
#include "nirslam/capture/pixel_format.hpp"
#include "nirslam/sources/source.hpp"

namespace nirslam {

class V4l2Io;

// Everything a V4L2 source string says. "v4l2:/dev/video0?format=Y16&size=640x480&fps=30" opens
// a real camera; "v4l2-emulated:/dev/video0?..." the emulated driver's camera at that node
// (mono at /dev/video0, side-by-side stereo at /dev/video2).
struct V4l2SourceSpec {
  std::string device = "/dev/video0";
  bool emulated = false;
  std::optional<PixelFormat> format;  // default: the device's first convertible format
  int width = 0;                      // 0: the device's first size for the format
  int height = 0;
  double fps = 0.0;                   // 0: the device's current rate
  int buffer_count = 4;               // memory-mapped driver buffers (2..32)
  int queue_capacity = 4;             // frames waiting for the consumer before the oldest is dropped
  bool stereo_side_by_side = false;   // split each frame; the left half is the SLAM frame
  std::optional<double> exposure_ms;  // set at start (turns auto exposure off)
  std::optional<double> gain;         // set at start, device units
  std::optional<bool> auto_exposure;
  bool locked = false;                // hold exposure and gain from the start
  double reconnect_wait_s = 3.0;      // after an unplug, how long next() waits for the device to return
  double stall_timeout_s = 5.0;       // a present device that sends no frame this long fails the stream
  double gain_unity = 0.0;            // device gain that is 1x for Frame::gain; 0: the control's default
  int emulated_frames = 0;            // emulated: unplug after this many frames (0: never)
  bool emulated_paced = true;         // emulated: frames at the device rate in real time

  std::string to_string() const;      // the spec back as a source string
};

// True for strings starting "v4l2:" or "v4l2-emulated:".
bool is_v4l2_source_string(std::string_view text);

// Parses a source string. Keys: format (GREY|Y10|Y12|Y16|YUYV|MJPG), size (WxH), fps, buffers,
// queue, stereo (sbs|none), exposure_ms, gain, auto_exposure (on|off), lock (on|off),
// reconnect_s, stall_s, gain_unity, and for the emulator frames and paced (on|off). Throws InputError
// naming the string and the key for an unknown key or a malformed value.
V4l2SourceSpec parse_v4l2_source_spec(std::string_view text);

// A live camera: a capture thread streams from the device into a small bounded queue (oldest
// frame dropped and counted when the consumer lags, so neither the UI nor the worker ever waits
// on the driver), with the exposure and gain in effect attached to every frame. An unplug ends the
// stream cleanly: the frames already captured are delivered, then next() waits up to
// reconnect_wait_s for the node to come back and streams on, or returns std::nullopt (end) with
// the reason in controls()->state(); rewind() reopens it later. A device that stays present but
// sends nothing for stall_timeout_s makes next() throw, so the worker never hangs on a camera. Opening throws InputError naming
// the device and the field (busy, unsupported format or size, control out of range).
class V4l2Source : public Source {
public:
  // The controls the GUI and worker drive; shared so they outlive a source being replaced.
  virtual std::shared_ptr<CameraControls> controls() const = 0;
  std::shared_ptr<CameraControls> camera_controls() const override { return controls(); }
  // The right half of the last frame next() returned, for a side-by-side stereo camera.
  virtual std::optional<cv::Mat> last_right_image() const = 0;
};

// Opens the camera the spec names: through libv4l2, or through a new emulated driver with the
// emulated cameras (spec.emulated).
std::unique_ptr<V4l2Source> open_v4l2_source(const V4l2SourceSpec& spec);
// The same, through a given seam (tests script the emulated driver they pass).
std::unique_ptr<V4l2Source> open_v4l2_source(const V4l2SourceSpec& spec, std::shared_ptr<V4l2Io> io);

}  // namespace nirslam
