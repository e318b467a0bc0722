#include "frontends/headless_frontend.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "frontends/egl_context.hpp"
#include "nirslam/image/image_codec.hpp"
#include "ui/application.hpp"
#include "ui/gl/gl.hpp"
#include "ui/gl/shader.hpp"
#include "ui/ui_context.hpp"

namespace nirslam::app {

void check_screenshot_folder(const std::filesystem::path& path) {
  const auto parent = path.parent_path();
  std::error_code error;
  if (!parent.empty() && !std::filesystem::is_directory(parent, error))
    throw std::runtime_error(fmt::format("cannot write screenshot {}: folder {} does not exist", path.string(),
                                         parent.string()));
}

void write_png_rgba(const std::filesystem::path& path, const cv::Mat& rgba) {
  check_screenshot_folder(path);
  cv::Mat bgr;
  cv::cvtColor(rgba, bgr, cv::COLOR_RGBA2BGR);
  try {
    write_image(path, bgr, ImageWriteOptions{.png = {.compression_level = 9}});
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("cannot write screenshot: {}", e.what()));  // names the file
  }
}

FrameTimeSummary summarise_frame_times(std::vector<double> frame_ms) {
  FrameTimeSummary summary;
  summary.frames = frame_ms.size();
  if (frame_ms.empty()) return summary;
  std::sort(frame_ms.begin(), frame_ms.end());
  double total = 0.0;
  for (const double ms : frame_ms) total += ms;
  const auto at = [&frame_ms](double q) {
    const auto i = static_cast<std::size_t>(std::ceil(q * static_cast<double>(frame_ms.size()))) ;
    return frame_ms[std::min(frame_ms.size() - 1, i == 0 ? 0 : i - 1)];
  };
  summary.mean_ms = total / static_cast<double>(frame_ms.size());
  summary.median_ms = at(0.5);
  summary.p95_ms = at(0.95);
  summary.p99_ms = at(0.99);
  summary.max_ms = frame_ms.back();
  summary.fps = summary.mean_ms > 0.0 ? 1000.0 / summary.mean_ms : 0.0;
  return summary;
}

HeadlessResult run_headless(Worker& worker, const HeadlessOptions& options) {
  if (options.width < 800 || options.height < 500)
    throw std::invalid_argument(fmt::format("headless size {}x{} is too small for the UI (at least 800x500)",
                                            options.width, options.height));
  if (options.screenshot.empty()) throw std::invalid_argument("headless rendering needs a screenshot path");
  check_screenshot_folder(options.screenshot);  // fail before the work, not after it

  EglContext egl;
  spdlog::debug("headless OpenGL: {}", egl.description());
  const auto shader_dir = ui::gl::find_shader_dir();
  spdlog::debug("shaders from {}", shader_dir.string());

  ui::OffscreenUi offscreen(options.width, options.height);
  ui::Application app(shader_dir, [&worker](Command c) { worker.post(std::move(c)); });
  if (options.preferences != nullptr) app.apply(*options.preferences);
  if (!options.tab.empty()) app.select_tab(options.tab);
  app.set_session_actions(options.session_actions);
  if (!options.current_source.empty()) app.session().set_current(options.current_source);

  HeadlessResult result;
  result.renderer = egl.description();
  const auto done = [&](const Snapshot& s) { return s.frames_processed >= options.frames || settled(s); };

  using Clock = std::chrono::steady_clock;
  const auto started = Clock::now();
  auto last_frame = started;
  const auto render = [&](const Snapshot& snapshot) {
    const auto now = Clock::now();
    const double delta = std::chrono::duration<double>(now - last_frame).count();
    last_frame = now;
    offscreen.frame([&] { app.draw(snapshot); }, delta);
    if (options.benchmark) {
      glFinish();  // llvmpipe renders asynchronously: count the frame when its pixels exist
      result.ui_frame_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - now).count());
    }
    ++result.ui_frames;
  };

  worker.post(command::Start{});
  std::shared_ptr<const Snapshot> shown = worker.snapshot();
  const std::int64_t frames_at_start = shown->frames_processed;
  while (true) {
    // About 30 UI frames a second while the worker runs, as a window would show them; the
    // benchmark draws back to back, taking whatever snapshot is newest (never waiting for one).
    shown = options.benchmark ? worker.snapshot() : worker.wait_for(done, std::chrono::milliseconds(33));
    render(*shown);
    if (done(*shown)) break;
    if (Clock::now() - started > options.timeout) {
      worker.post(command::Pause{});
      throw std::runtime_error(fmt::format("headless rendering timed out after {} s with {} of {} frames processed",
                                           std::chrono::duration_cast<std::chrono::seconds>(options.timeout).count(),
                                           shown->frames_processed, options.frames));
    }
  }
  worker.post(command::Pause{});
  if (options.benchmark) {
    const double seconds = std::chrono::duration<double>(Clock::now() - started).count();
    result.worker_fps = seconds > 0.0 ? static_cast<double>(shown->frames_processed - frames_at_start) / seconds : 0.0;
  }
  // The screenshot shows the snapshot that met the target; two more UI frames let every widget
  // settle on its final size (ImGui measures some text a frame late).
  render(*shown);
  render(*shown);

  write_png_rgba(options.screenshot, offscreen.read_rgba());
  result.screenshot = options.screenshot;
  result.frames_processed = shown->frames_processed;
  result.final_state = shown->state;
  result.message = shown->message;
  result.reached_frames = shown->frames_processed >= options.frames;
  return result;
}

}  // namespace nirslam::app
