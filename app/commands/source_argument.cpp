#include "commands/source_argument.hpp"

#include <filesystem>

#include "commands/app_config.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/demo_source.hpp"
#include "nirslam/sources/open_source.hpp"

namespace nirslam::app {

bool is_built_in_sequence(const std::string& argument) {
  return argument == "demo" || argument == "sim" || argument.rfind("sim:", 0) == 0;
}

SourceFactory source_factory_from_argument(const std::string& argument) {
  if (argument == "demo") return [demo = app_config().demo] { return make_demo_source(demo); };
  if (argument == "sim" || argument.rfind("sim:", 0) == 0) {
    SimulatorOptions options;
    if (argument != "sim") {
      const auto scene = sim::parse_scene_kind(argument.substr(4));
      if (!scene)
        throw std::invalid_argument("unknown simulated scene '" + argument.substr(4) +
                                    "' (expected sim:room, sim:outdoor, sim:parking or sim:tunnel)");
      options.scene = *scene;
    }
    validate(options);
    return [options] { return make_simulated_source(options); };
  }
  const std::filesystem::path path(argument);
  if (!std::filesystem::exists(path)) throw InputError(path, "no such file or folder");
  return [path] { return open_source(path); };
}

}  // namespace nirslam::app
