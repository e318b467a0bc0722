#pragma once

#include <filesystem>
#include <optional>
#include <string_view>
#include <utility>

#include <imgui.h>

#include "nirslam/config/ui_preferences.hpp"
#include "nirslam/illumination/sweep_camera_lock.hpp"
#include "nirslam/worker/snapshot.hpp"
#include "ui/command_sink.hpp"
#include "ui/panels/camera_panel.hpp"
#include "ui/panels/control_bar.hpp"
#include "ui/panels/entropy_panel.hpp"
#include "ui/panels/feed_panel.hpp"
#include "ui/panels/illumination_panel.hpp"
#include "ui/panels/notification_area.hpp"
#include "ui/panels/photometric_panel.hpp"
#include "ui/panels/recording_panel.hpp"
#include "ui/panels/session_panel.hpp"
#include "ui/panels/shortcut_help.hpp"
#include "ui/panels/status_bar.hpp"
#include "ui/panels/trajectory_panel.hpp"
#include "ui/shortcuts.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// Which parts of the layout are drawn. Tests render one panel alone.
struct PanelSet {
  bool controls = true;
  bool feed = true;
  bool entropy = true;
  bool illumination = true;
  bool photometric = true;
  bool session = true;
  bool record = true;
  bool camera = true;
  bool view3d = true;
  bool status = true;
};

// The operator UI: owns the panels and their tiled layout and draws one UI frame from a
// snapshot. It reads snapshots and posts commands; it never waits on the worker.
//
// Dear ImGui 1.86 (Debian) has no docking branch, so the layout is a fixed tiling of windows
// that follows the display size: control strip on top, status line at the bottom, the feed and
// the 3-D view side by side on the left with a strip under them (illumination and photometric
// curves as tabs), and the image-quality column on the right. Nothing overlaps.
class Application {
public:
  // Loads the panels' shaders from `shader_dir` (see gl::find_shader_dir()); throws
  // gl::ShaderError naming the file. Needs a current GL context and a UiContext.
  Application(const std::filesystem::path& shader_dir, CommandSink post);

  // Draws the whole layout, between UiContext::begin_frame() and end_frame(). Handles the
  // keyboard shortcuts of ui/shortcuts.hpp (Space pauses or resumes, S steps, H lists them all).
  void draw(const Snapshot& snapshot);

  // How the Session tab opens sources (the app's job); without it the picker is disabled.
  void set_session_actions(SessionActions actions) { session_actions_ = std::move(actions); }

  // The operator's choices: restored at start (views, tab, recent sources, playback) and read
  // back at exit. apply() posts the pipeline mode and pacing when there is a sink.
  void apply(const UiPreferences& preferences);
  void capture(UiPreferences& preferences) const;

  struct Layout {
    ScreenRect controls;
    ScreenRect feed;
    ScreenRect view3d;
    ScreenRect entropy;
    ScreenRect strip;  // the illumination and photometric tabs
    ScreenRect status;
  };
  // The tiling for a display size with the current ImGui style and font (call inside a frame).
  Layout compute_layout(ImVec2 display) const;
  const Layout& layout() const { return layout_; }

  PanelSet panels;
  FeedPanel& feed() { return feed_; }
  EntropyPanel& entropy() { return entropy_; }
  IlluminationPanel& illumination() { return illumination_; }
  PhotometricPanel& photometric() { return photometric_; }
  TrajectoryPanel& view3d() { return view3d_; }
  SessionPanel& session() { return session_; }
  RecordingPanel& recording() { return recording_; }
  CameraPanel& camera() { return camera_; }
  NotificationArea& notifications() { return notifications_; }
  ShortcutHelp& shortcut_help() { return help_; }

  enum class StripTab { Illumination, Photometric, Session, Record, Camera };
  // The tab to bring to the front on the next draw (the tab bar remembers the operator's choice).
  void select_tab(StripTab tab) { requested_tab_ = tab; }
  // By the name the settings and `gui --tab` use ("illumination", ..., "camera"); false if unknown.
  bool select_tab(std::string_view name);
  StripTab current_tab() const { return current_tab_; }

private:
  void handle_shortcuts(const Snapshot& snapshot);
  void draw_strip(const Snapshot& snapshot);
  void run_shortcut(ShortcutAction action, const Snapshot& snapshot);
  void draw_camera_tab();
  void watch_camera();
  void lock_camera_for_sweep(const Snapshot& snapshot);

  CommandSink post_;
  ControlBar controls_;
  FeedPanel feed_;
  EntropyPanel entropy_;
  IlluminationPanel illumination_;
  PhotometricPanel photometric_;
  TrajectoryPanel view3d_;
  StatusBar status_;
  SessionPanel session_;
  RecordingPanel recording_;
  CameraPanel camera_;
  std::optional<CameraConnection> camera_connection_;  // last seen, to notify on unplug / failure
  SweepCameraLock sweep_camera_lock_;
  SessionActions session_actions_;
  NotificationArea notifications_;
  ShortcutHelp help_;
  std::optional<StripTab> requested_tab_;
  StripTab current_tab_ = StripTab::Illumination;
  Layout layout_;
};

}  // namespace nirslam::ui
