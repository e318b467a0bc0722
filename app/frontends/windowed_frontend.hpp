#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "nirslam/worker/worker.hpp"

namespace nirslam::app {

struct WindowedOptions {
  int width = 1440;                  // initial window size in screen coordinates (before HiDPI scale)
  int height = 900;
  std::string title = "nirslam";
  // When set: the window's contents are saved as PNG once the worker has processed this many
  // frames (the window stays open).
  std::filesystem::path screenshot;
  std::int64_t screenshot_after_frames = 60;
  bool photometric_tab = false;      // open on the Photometric tab of the strip
};

// The operator GUI in a GLFW window (OpenGL 3.3 core, vsync, ImGui GLFW + OpenGL3 backends).
// Starts the worker (its source must be set) and runs until the window is closed (or Ctrl+Q),
// then stops the worker. Throws FrontendUnavailable when no window can be opened (no display, no GL 3.3), before
// anything was shown, so the caller can fall back to the headless front end.
void run_windowed(Worker& worker, const WindowedOptions& options);

}  // namespace nirslam::app
