#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/source_argument.hpp"
#include "commands/subcommand.hpp"
#include "frontends/frontend_error.hpp"
#include "frontends/headless_frontend.hpp"
#include "frontends/windowed_frontend.hpp"
#include "nirslam/capture/device_info.hpp"
#include "nirslam/capture/emulated_uvc.hpp"
#include "nirslam/capture/v4l2_io.hpp"
#include "nirslam/config/ui_preferences.hpp"
#include "nirslam/session/session_recovery.hpp"
#include "nirslam/worker/worker.hpp"
#include "ui/panels/recording_panel.hpp"

namespace nirslam::app {
namespace {

struct GuiOptions {
  std::string source = kDefaultSource;
  bool headless = false;
  std::int64_t frames = 60;
  std::filesystem::path screenshot;
  std::string size;        // "WxH"; empty: the front end's default
  bool fast = false;       // windowed: process as fast as possible instead of at recorded speed
  bool loop = false;       // restart the source at its end
  std::string tab;                     // the strip tab shown first; empty: illumination, or as saved
  bool source_given = false;           // a SOURCE was on the command line (else: the last one, windowed)
  bool no_settings = false;            // neither read nor write the operator's settings
  bool ui_benchmark = false;           // headless: print UI frame times while the pipeline runs
};

struct Size {
  int width = 0;
  int height = 0;
};

std::optional<Size> parse_size(const std::string& text) {
  const auto x = text.find_first_of("xX");
  if (x == std::string::npos || x == 0 || x + 1 >= text.size()) return std::nullopt;
  try {
    std::size_t used_w = 0;
    std::size_t used_h = 0;
    const int w = std::stoi(text.substr(0, x), &used_w);
    const int h = std::stoi(text.substr(x + 1), &used_h);
    if (used_w != x || used_h != text.size() - x - 1) return std::nullopt;
    return Size{w, h};
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::string check_size(const std::string& text) {
  const auto size = parse_size(text);
  if (!size) return "expected WIDTHxHEIGHT, e.g. 1280x800";
  if (size->width < 800 || size->height < 500 || size->width > 8192 || size->height > 8192)
    return "the size must be between 800x500 and 8192x8192";
  return {};
}

bool has_display() {
  const auto set = [](const char* name) {
    const char* value = std::getenv(name);
    return value != nullptr && *value != '\0';
  };
  return set("DISPLAY") || set("WAYLAND_DISPLAY");
}

// The controls of the camera the worker streams from: set on the worker thread when a factory
// opens a source, read by the UI's camera panel every frame.
class CameraSlot {
public:
  void set(std::shared_ptr<CameraControls> controls) {
    const std::lock_guard lock(mutex_);
    controls_ = std::move(controls);
  }
  std::shared_ptr<CameraControls> get() const {
    const std::lock_guard lock(mutex_);
    return controls_;
  }

private:
  mutable std::mutex mutex_;
  std::shared_ptr<CameraControls> controls_;
};

SourceFactory factory_for(const std::string& source, const std::shared_ptr<CameraSlot>& cameras) {
  return source_factory_from_argument(source, [cameras](std::shared_ptr<CameraControls> controls) {
    cameras->set(std::move(controls));
  });
}

// The Session tab's Open: the same SOURCE strings as the command line, checked now (a refusal is
// shown in the panel), opened on the worker thread (a failure there shows as a notification).
ui::SessionActions session_actions(Worker& worker, const std::shared_ptr<CameraSlot>& cameras) {
  ui::SessionActions actions;
  actions.open_source = [&worker, cameras](const std::string& source) -> std::string {
    try {
      SourceFactory factory = factory_for(source, cameras);
      worker.post(command::SetSource{std::move(factory)});
      worker.post(command::Start{});
      return {};
    } catch (const std::exception& e) {
      return e.what();
    }
  };
  actions.list_cameras = [](bool emulated) {
    const std::shared_ptr<V4l2Io> io =
        emulated ? std::shared_ptr<V4l2Io>(make_emulated_nir_cameras()) : make_system_v4l2_io();
    return enumerate_devices(*io);
  };
  actions.camera_controls = [cameras] { return cameras->get(); };
  return actions;
}

void print_ui_benchmark(const HeadlessResult& result, const HeadlessOptions& options, const std::string& source,
                        const std::string& mode) {
  // The first frames build font atlases and upload shaders: not what an operator sees.
  std::vector<double> steady = result.ui_frame_ms;
  const std::size_t warm_up = std::min<std::size_t>(10, steady.size() / 4);
  steady.erase(steady.begin(), steady.begin() + static_cast<std::ptrdiff_t>(warm_up));
  const FrameTimeSummary s = summarise_frame_times(std::move(steady));
  std::printf("UI frame times, %dx%d, source %s, pipeline %s, renderer %s\n", options.width, options.height,
              source.c_str(), mode.c_str(), result.renderer.c_str());
  std::printf("  %zu UI frames (after %zu warm-up): mean %.2f ms, median %.2f, p95 %.2f, p99 %.2f, max %.2f ms\n",
              s.frames, warm_up, s.mean_ms, s.median_ms, s.p95_ms, s.p99_ms, s.max_ms);
  std::printf("  UI %.1f frames/s while the worker processed %.1f frames/s (%lld frames)\n", s.fps, result.worker_fps,
              static_cast<long long>(result.frames_processed));
}

int headless(Worker& worker, const GuiOptions& options, const std::filesystem::path& screenshot,
             const std::shared_ptr<CameraSlot>& cameras) {
  HeadlessOptions headless_options;
  headless_options.benchmark = options.ui_benchmark;
  headless_options.session_actions = session_actions(worker, cameras);
  headless_options.current_source = options.source;
  headless_options.frames = options.frames;
  headless_options.screenshot = screenshot;
  headless_options.tab = options.tab;
  if (!options.size.empty()) {
    const Size size = *parse_size(options.size);
    headless_options.width = size.width;
    headless_options.height = size.height;
  }
  const HeadlessResult result = run_headless(worker, headless_options);
  if (options.ui_benchmark)
    print_ui_benchmark(result, headless_options, options.source, std::string(to_string(app_config().worker.pipeline.mode)));
  if (result.final_state == WorkerState::Failed) {
    spdlog::error("the source failed: {}", result.message);
    std::printf("Screenshot of the failure written to %s\n", result.screenshot.string().c_str());
    return 1;
  }
  if (!result.reached_frames)
    spdlog::warn("the source ended after {} frames, before the {} asked for", result.frames_processed, options.frames);
  std::printf("Screenshot written to %s (%dx%d, after %lld frames, %d UI frames)\n", result.screenshot.string().c_str(),
              headless_options.width, headless_options.height, static_cast<long long>(result.frames_processed),
              result.ui_frames);
  return 0;
}

int run_gui(GuiOptions options) {
  const bool windowed = !options.headless;
  // A window remembers the operator's choices; headless runs (tests, reports) stay reproducible
  // and neither read nor write them.
  const bool use_settings = windowed && !options.no_settings;
  const std::filesystem::path settings_file = default_preferences_path();
  LoadedPreferences settings;
  if (use_settings) settings = load_preferences(settings_file);
  for (const std::string& warning : settings.warnings) spdlog::warn("{}", warning);
  std::vector<std::string> startup_warnings = settings.warnings;
  if (use_settings) {
    // A crash or power cut during the last recording left a session unfinished: repair it now,
    // before the operator replays or exports it, and say so in the window.
    const std::filesystem::path sessions = settings.preferences.sessions_folder.empty()
                                               ? ui::default_sessions_folder()
                                               : std::filesystem::path(settings.preferences.sessions_folder);
    for (const RecoveryReport& report : recover_unfinished_sessions(sessions))
      startup_warnings.push_back(fmt::format("Recovered an unfinished session: {}", report.summary));
  }

  const auto cameras = std::make_shared<CameraSlot>();
  SourceFactory factory;
  if (use_settings && !options.source_given && !settings.preferences.last_source.empty()) {
    try {
      factory = factory_for(settings.preferences.last_source, cameras);
      options.source = settings.preferences.last_source;
    } catch (const std::exception& e) {
      startup_warnings.push_back(fmt::format("The last source cannot be opened again ({}); showing {} instead.",
                                             e.what(), kDefaultSource));
    }
  }
  if (!factory) factory = factory_for(options.source, cameras);
  const bool built_in = is_built_in_sequence(options.source);
  WorkerOptions worker_options = app_config().worker;
  // A window shows the sequence at its own pace; headless (and --fast) goes as fast as it can.
  // The UI benchmark plays the sequence at its own pace too, as a live camera would deliver it.
  worker_options.pacing =
      (windowed || options.ui_benchmark) && !options.fast ? Pacing::RecordedSpeed : Pacing::AsFastAsPossible;
  worker_options.loop = options.loop || (windowed && built_in);
  Worker worker(worker_options);
  worker.post(command::SetSource{factory});

  if (options.headless) {
    return headless(worker, options, options.screenshot.empty() ? "nirslam-gui.png" : options.screenshot, cameras);
  }
  WindowedOptions window_options;
  window_options.title = fmt::format("nirslam — {}", options.source);
  window_options.session_actions = session_actions(worker, cameras);
  window_options.current_source = options.source;
  window_options.startup_warnings = std::move(startup_warnings);
  UiPreferences& preferences = settings.preferences;
  remember_source(preferences, options.source);
  if (use_settings) {
    window_options.preferences = &preferences;
    window_options.size_from_preferences = options.size.empty();
  }
  window_options.screenshot = options.screenshot;
  window_options.screenshot_after_frames = options.frames;
  window_options.tab = options.tab;
  if (!options.size.empty()) {
    const Size size = *parse_size(options.size);
    window_options.width = size.width;
    window_options.height = size.height;
  }
  run_windowed(worker, window_options);
  if (use_settings) {
    try {
      save_preferences(settings_file, preferences);
    } catch (const std::exception& e) {
      spdlog::warn("settings not saved: {}", e.what());
    }
  }
  return 0;
}

}  // namespace

void add_gui_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<GuiOptions>();
  CLI::App* gui = parent.add_subcommand(
      "gui", "Open the operator GUI on a dataset or a simulated scene: live feed, image quality, illumination advice,\n"
             "3-D trajectory and photometric calibration.\n"
             "With --headless it renders offscreen (EGL, no display needed) and writes a PNG.");
  CLI::Option* source = gui->add_option("source", options->source, std::string(kSourceArgumentHelp) +
                                         ". Default: the last source of a window (see --no-settings), else sim:tunnel");
  gui->add_flag("--headless", options->headless, "Render offscreen without a window and write a screenshot");
  gui->add_option("--frames", options->frames,
                  "Headless: render until this many frames were processed; windowed: when to take --screenshot")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  gui->add_option("--screenshot", options->screenshot,
                  "PNG to write (headless default: nirslam-gui.png; windowed: none)");
  gui->add_option("--size", options->size, "Window or image size as WIDTHxHEIGHT (default 1440x900 windowed, 1280x800 headless)")
      ->check(CLI::Validator(check_size, "WxH"));
  gui->add_flag("--fast", options->fast, "Windowed: process frames as fast as possible instead of at recorded speed");
  gui->add_option("--tab", options->tab,
                  "The tab shown first under the feed: illumination, photometric, session, record or camera "
                  "(default: the last one of a window, else illumination)")
      ->check(CLI::IsMember({"illumination", "photometric", "session", "record", "camera"}));
  gui->add_flag("--loop", options->loop, "Restart the source at its end (built-in sequences always loop in a window)");
  gui->add_flag("--no-settings", options->no_settings,
                "Windowed: ignore the saved settings (last source, views, window) and do not save them "
                "(they live in $NIRSLAM_SETTINGS, else ~/.config/nirslam/settings.json)");
  gui->add_flag("--ui-benchmark", options->ui_benchmark,
                "Headless: draw UI frames back to back while the pipeline runs and print their times "
                "(mean, percentiles, UI frames/s)");
  gui->callback([&action, options, source] {
    options->source_given = source->count() > 0;
    action = [options] {
      try {
        return run_gui(*options);
      } catch (const FrontendUnavailable& e) {
        if (options->headless) throw;
        throw FrontendUnavailable(std::string(e.what()) + " (use --headless to render without a display)");
      }
    };
  });
}

int run_default_gui() {
  if (has_display()) {
    try {
      GuiOptions options;
      return run_gui(options);
    } catch (const FrontendUnavailable& e) {
      std::printf("%s; rendering the simulated tunnel headless instead.\n", e.what());
    }
  } else {
    std::printf("No display (DISPLAY and WAYLAND_DISPLAY are unset): rendering the simulated tunnel headless.\n");
  }
  GuiOptions options;
  options.headless = true;
  options.frames = 60;
  options.screenshot = "nirslam-demo.png";
  return run_gui(options);
}

}  // namespace nirslam::app
