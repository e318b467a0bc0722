#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "nirslam/config/ui_preferences.hpp"
#include "nirslam/worker/worker.hpp"
#include "ui/panels/session_panel.hpp"

namespace nirslam::app {

struct WindowedOptions {
  int width = 1440;                  // initial window size in screen coordinates (before HiDPI scale)
  int height = 900;
  std::string title = "nirslam";
  // When set: the window's contents are saved as PNG once the worker has processed this many
  // frames (the window stays open).
  std::filesystem::path screenshot;
  std::int64_t screenshot_after_frames = 60;
  std::string tab;                     // the strip tab shown first: "illumination", "photometric", "session"; empty: as saved
  ui::SessionActions session_actions;  // how the Session tab opens sources
  std::string current_source;          // the SOURCE the worker was given, shown in the Session tab
  // The operator's settings: applied at start (views, tab, window position and size unless
  // `width`/`height` were given explicitly) and updated at exit, when given.
  UiPreferences* preferences = nullptr;
  bool size_from_preferences = false;   // take the window size from `preferences`
  std::vector<std::string> startup_warnings;  // shown in the window (e.g. a damaged settings file)
};

// The operator GUI in a GLFW window (OpenGL 3.3 core, vsync, ImGui GLFW + OpenGL3 backends).
// Starts the worker (its source must be set) and runs until the window is closed (or Ctrl+Q),
// then stops the worker. Throws FrontendUnavailable when no window can be opened (no display, no GL 3.3), before
// anything was shown, so the caller can fall back to the headless front end.
void run_windowed(Worker& worker, const WindowedOptions& options);

}  // namespace nirslam::app
