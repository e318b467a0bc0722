#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/config/ui_preferences.hpp"
#include "nirslam/worker/worker.hpp"
#include "ui/panels/session_panel.hpp"

namespace nirslam::app {

struct HeadlessOptions {
  int width = 1280;
  int height = 800;
  std::int64_t frames = 60;            // render until the worker has processed at least this many
  std::filesystem::path screenshot;    // PNG written at the end
  std::chrono::milliseconds timeout{120000};
  std::string tab;                     // the strip tab shown first: "illumination", "photometric", "session"; empty: as saved
  // UI frame-rate benchmark: draw UI frames back to back (no 30 Hz pacing), each finished on the
  // GPU (glFinish) so its time is the real cost, and keep every frame time in the result.
  bool benchmark = false;
  ui::SessionActions session_actions;  // how the Session tab opens sources (optional)
  std::string current_source;          // the SOURCE the worker was given, shown in the Session tab
  const UiPreferences* preferences = nullptr;  // applied to the UI at start, when given
};

struct HeadlessResult {
  std::filesystem::path screenshot;
  std::int64_t frames_processed = 0;
  int ui_frames = 0;
  WorkerState final_state = WorkerState::Idle;
  std::string message;                 // the worker's last message
  std::string renderer;                // the GL renderer, for the log
  bool reached_frames = false;         // false when the source ended or failed first
  std::vector<double> ui_frame_ms;     // benchmark: the time of every UI frame, in order
  double worker_fps = 0.0;             // benchmark: frames the worker processed per second meanwhile
};

// Mean, percentiles and rate of UI frame times, as `gui --headless --ui-benchmark` prints them.
struct FrameTimeSummary {
  std::size_t frames = 0;
  double mean_ms = 0.0;
  double median_ms = 0.0;
  double p95_ms = 0.0;
  double p99_ms = 0.0;
  double max_ms = 0.0;
  double fps = 0.0;                    // 1000 / mean
};
FrameTimeSummary summarise_frame_times(std::vector<double> frame_ms);

// The UI without a window: an EGL surfaceless OpenGL 3.3 context, the whole layout rendered into
// an offscreen framebuffer of the given size, ImGui fed the display size by hand. Starts the
// worker (whose source must be set), renders UI frames while it processes frames until `frames`
// were processed (or the source ended or failed), then pauses it, renders the final state, reads
// the pixels back and writes the PNG. Throws FrontendUnavailable when EGL/OpenGL is missing,
// std::runtime_error when the screenshot cannot be written or the timeout passes.
HeadlessResult run_headless(Worker& worker, const HeadlessOptions& options);

// Throws std::runtime_error naming the folder when the screenshot's folder does not exist.
void check_screenshot_folder(const std::filesystem::path& path);

// Writes an RGBA image (top row first) as PNG. Throws std::runtime_error naming the path.
void write_png_rgba(const std::filesystem::path& path, const cv::Mat& rgba);

}  // namespace nirslam::app
