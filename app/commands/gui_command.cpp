#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/source_argument.hpp"
#include "commands/subcommand.hpp"
#include "frontends/frontend_error.hpp"
#include "frontends/headless_frontend.hpp"
#include "frontends/windowed_frontend.hpp"
#include "nirslam/worker/worker.hpp"

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
  std::string tab = "illumination";  // the strip tab shown first
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

int headless(Worker& worker, const GuiOptions& options, const std::filesystem::path& screenshot) {
  HeadlessOptions headless_options;
  headless_options.frames = options.frames;
  headless_options.screenshot = screenshot;
  headless_options.photometric_tab = options.tab == "photometric";
  if (!options.size.empty()) {
    const Size size = *parse_size(options.size);
    headless_options.width = size.width;
    headless_options.height = size.height;
  }
  const HeadlessResult result = run_headless(worker, headless_options);
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

int run_gui(const GuiOptions& options) {
  const SourceFactory factory = source_factory_from_argument(options.source);
  const bool built_in = is_built_in_sequence(options.source);
  const bool windowed = !options.headless;
  WorkerOptions worker_options = app_config().worker;
  // A window shows the sequence at its own pace; headless (and --fast) goes as fast as it can.
  worker_options.pacing = windowed && !options.fast ? Pacing::RecordedSpeed : Pacing::AsFastAsPossible;
  worker_options.loop = options.loop || (windowed && built_in);
  Worker worker(worker_options);
  worker.post(command::SetSource{factory});

  if (options.headless) {
    return headless(worker, options, options.screenshot.empty() ? "nirslam-gui.png" : options.screenshot);
  }
  WindowedOptions window_options;
  window_options.title = fmt::format("nirslam — {}", options.source);
  window_options.screenshot = options.screenshot;
  window_options.screenshot_after_frames = options.frames;
  window_options.photometric_tab = options.tab == "photometric";
  if (!options.size.empty()) {
    const Size size = *parse_size(options.size);
    window_options.width = size.width;
    window_options.height = size.height;
  }
  run_windowed(worker, window_options);
  return 0;
}

}  // namespace

void add_gui_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<GuiOptions>();
  CLI::App* gui = parent.add_subcommand(
      "gui", "Open the operator GUI on a dataset or a simulated scene: live feed, image quality, illumination advice,\n"
             "3-D trajectory and photometric calibration.\n"
             "With --headless it renders offscreen (EGL, no display needed) and writes a PNG.");
  gui->add_option("source", options->source, kSourceArgumentHelp)->capture_default_str();
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
  gui->add_option("--tab", options->tab, "The tab shown first under the feed: illumination or photometric")
      ->check(CLI::IsMember({"illumination", "photometric"}))
      ->capture_default_str();
  gui->add_flag("--loop", options->loop, "Restart the source at its end (built-in sequences always loop in a window)");
  gui->callback([&action, options] {
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
