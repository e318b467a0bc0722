#include "commands/source_argument.hpp"

#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "commands/app_config.hpp"
#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/session/session_format.hpp"
#include "nirslam/session/session_source.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/demo_source.hpp"
#include "nirslam/sources/open_source.hpp"

namespace nirslam::app {

namespace {

// A number in (0, 1000] (watts, milliseconds), the whole of `text`; else `complaint` about `argument`.
double parse_up_to_a_thousand(const std::string& text, const std::string& argument, const char* complaint) {
  double value = 0.0;
  std::size_t used = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !(value > 0.0) || value > 1000.0)
    throw std::invalid_argument("'" + argument + "': " + complaint);
  return value;
}

double parse_power(std::string text, const std::string& argument) {
  if (!text.empty() && (text.back() == 'W' || text.back() == 'w')) text.pop_back();
  return parse_up_to_a_thousand(text, argument,
                                "the lamp power after '@' must be a number of watts in (0, 1000], e.g. sim:tunnel@50W");
}

double parse_exposure(const std::string& text, const std::string& argument) {
  return parse_up_to_a_thousand(text, argument, "exposure= must be milliseconds in (0, 1000], e.g. sim:room/exposure=4");
}

}  // namespace

bool is_built_in_sequence(const std::string& argument) {
  return argument == "demo" || argument == "sim" || argument.rfind("sim:", 0) == 0;
}

SourceFactory source_factory_from_argument(const std::string& argument) {
  if (argument == "demo") return [demo = app_config().demo] { return make_demo_source(demo); };
  if (argument == "sim" || argument.rfind("sim:", 0) == 0) {
    SimulatorOptions options;
    if (argument != "sim") {
      // sim:SCENE[@POWER][/OPTION...]: the lamp's power at the start in watts ("W" optional); the
      // options a motion (handheld, vehicle, robot, tripod: the rig still, as a power sweep for
      // the response wants it) and exposure=MS (auto exposure off, the exposure fixed).
      std::vector<std::string> parts;
      std::stringstream fields(argument.substr(4));
      for (std::string part; std::getline(fields, part, '/');) parts.push_back(part);
      const std::string spec = parts.empty() ? std::string() : parts.front();
      const std::vector<std::string> extras(parts.begin() + (parts.empty() ? 0 : 1), parts.end());
      const std::string scene_name = spec.substr(0, spec.find('@'));
      const auto scene = sim::parse_scene_kind(scene_name);
      if (!scene)
        throw std::invalid_argument("unknown simulated scene '" + scene_name +
                                    "' (expected sim:room, sim:outdoor, sim:parking or sim:tunnel)");
      options.scene = *scene;
      if (const auto at = spec.find('@'); at != std::string::npos)
        options.powers_w = {parse_power(spec.substr(at + 1), argument)};
      for (const std::string& extra : extras) {
        if (const auto motion = sim::parse_motion_kind(extra)) {
          options.motion = *motion;
        } else if (extra.rfind("exposure=", 0) == 0) {
          options.exposure_mode = ExposureMode::Fixed;
          options.exposure_ms = parse_exposure(extra.substr(9), argument);
        } else {
          throw std::invalid_argument("'" + argument + "': unknown option '" + extra +
                                      "' after '/' (a motion: handheld, vehicle, robot, tripod; or exposure=MS)");
        }
      }
    }
    validate(options);
    return [options] { return make_simulated_source(options); };
  }
  if (is_v4l2_source_string(argument)) {
    // Parsed now, so a malformed key or value is reported before any window opens; the device is
    // opened on the worker thread.
    const V4l2SourceSpec spec = parse_v4l2_source_spec(argument);
    return [spec]() -> std::unique_ptr<Source> { return open_v4l2_source(spec); };
  }
  // session:FOLDER names a recorded session explicitly; a folder holding session.json is one too.
  const bool explicit_session = argument.rfind("session:", 0) == 0;
  const std::filesystem::path path(explicit_session ? argument.substr(8) : argument);
  if (!std::filesystem::exists(path)) throw InputError(path, "no such file or folder");
  if (explicit_session || is_session_folder(path)) {
    if (!is_session_folder(path))
      throw InputError(path, "not a recorded session (no session.json); record one with `nirslam record` or the GUI");
    return [path] { return open_session_source(path); };
  }
  return [path] { return open_source(path); };
}

SourceFactory source_factory_from_argument(const std::string& argument, CameraControlsSink on_open) {
  SourceFactory make = source_factory_from_argument(argument);
  if (!on_open) return make;
  return [make = std::move(make), on_open = std::move(on_open)]() -> std::unique_ptr<Source> {
    std::unique_ptr<Source> source = make();
    on_open(source->camera_controls());
    return source;
  };
}

}  // namespace nirslam::app
