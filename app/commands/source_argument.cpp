#include "commands/source_argument.hpp"

#include "commands/app_config.hpp"

#include <filesystem>

#include "nirslam/common/error.hpp"
#include "nirslam/sources/demo_source.hpp"
#include "nirslam/sources/open_source.hpp"

namespace nirslam::app {

SourceFactory source_factory_from_argument(const std::string& argument) {
  if (argument == "demo") return [demo = app_config().demo] { return make_demo_source(demo); };
  const std::filesystem::path path(argument);
  if (!std::filesystem::exists(path)) throw InputError(path, "no such file or folder");
  return [path] { return open_source(path); };
}

}  // namespace nirslam::app
