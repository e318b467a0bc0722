#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include "nirslam/capture/camera_controls.hpp"
#include "nirslam/capture/device_info.hpp"
#include "nirslam/worker/snapshot.hpp"
#include "ui/command_sink.hpp"
#include "ui/panels/device_list.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// What the session panel asks of the program around it. The UI library cannot open sources or
// devices itself (that is the app's business, and it must not block), so it names what the
// operator chose as a SOURCE string, exactly as on the command line, and the app answers.
struct SessionActions {
  // Accepts a source ("sim:tunnel@50W", a dataset or session folder, "v4l2:/dev/video0"), hands it
  // to the worker and returns an empty string; or returns why it was refused (no such folder, ...).
  std::function<std::string(const std::string& source)> open_source;
  // The V4L2 cameras (the emulated driver's with `emulated`); called when the operator asks, since
  // probing devices takes a moment. Without it the camera picker says cameras are unavailable.
  std::function<std::vector<DeviceInfo>(bool emulated)> list_cameras;
  // The controls of the camera the worker streams from now, nullptr when the source is not a camera.
  std::function<std::shared_ptr<CameraControls>()> camera_controls;
};

// Session: where the frames come from and how they are played.
//   - source picker: the simulator (scene and lamp power), a dataset folder (TUM monoVO, EuRoC,
//     image folder), a recorded session; Open hands it to the worker (Ctrl-free: Enter in the path
//     field opens too); a refusal is shown under the button, in red, until the next attempt,
//   - a V4L2 camera: the devices with their formats, sizes and rates (or the emulated driver's),
//   - recent sources, newest first, one click to reopen,
//   - playback: recorded speed or as fast as possible, the worker state and the position.
class SessionPanel {
public:
  enum class SourceKind { Simulator, Dataset, Recording, Camera };

  void draw(const Snapshot& snapshot, const CommandSink& post, const SessionActions& actions);

  // The recent list shown (newest first); the app fills it from the settings and reads it back.
  std::vector<std::string> recent_sources;
  // Opened sources are reported here so the app can remember them.
  std::function<void(const std::string& source)> on_source_opened;

  // Prefills the picker from a SOURCE string (the current or last source).
  void select(const std::string& source);
  // The source the worker has now (opened on the command line): prefilled and marked in the list.
  void set_current(const std::string& source) {
    select(source);
    last_opened_ = source;
  }
  // The SOURCE string the picker describes now ("" while incomplete).
  std::string chosen_source() const;
  SourceKind kind() const { return kind_; }
  const std::string& error() const { return error_; }
  bool recorded_speed() const { return recorded_speed_; }
  void set_recorded_speed(bool value) { recorded_speed_ = value; }

  // Geometry of the last draw(), for the screenshot tests.
  const ScreenRect& open_button_rect() const { return open_button_; }
  const ScreenRect& error_rect() const { return error_rect_; }
  const ScreenRect& recent_rect() const { return recent_rect_; }

private:
  void draw_picker(const SessionActions& actions);
  void draw_cameras(const SessionActions& actions);
  void draw_recent(const SessionActions& actions);
  void draw_playback(const Snapshot& snapshot, const CommandSink& post);
  void open(const std::string& source, const SessionActions& actions);

  SourceKind kind_ = SourceKind::Simulator;
  int scene_ = 0;                    // index into the scene list
  float power_w_ = 50.0f;
  std::array<char, 1024> dataset_path_{};
  std::array<char, 1024> session_path_{};
  std::string error_;
  std::string last_opened_;
  DeviceList device_list_;
  std::vector<DeviceInfo> devices_;
  bool emulated_cameras_ = false;
  bool devices_listed_ = false;
  bool recorded_speed_ = true;
  ScreenRect open_button_;
  ScreenRect error_rect_;
  ScreenRect recent_rect_;
};

}  // namespace nirslam::ui
