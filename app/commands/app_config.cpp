#include "commands/app_config.hpp"

#include <spdlog/spdlog.h>

#include "nirslam/common/resource_paths.hpp"

namespace nirslam::app {
namespace {

PipelineConfig& config_storage() {
  static PipelineConfig config;
  return config;
}

}  // namespace

void load_app_config(const std::filesystem::path& explicit_file) {
  if (!explicit_file.empty()) {
    config_storage() = load_pipeline_config(explicit_file);  // a file asked for must load
    spdlog::debug("configuration: {}", explicit_file.string());
    return;
  }
  try {
    const auto file = find_resource_dir(kConfigFolder) / "pipeline.yaml";
    config_storage() = load_pipeline_config(file);
    spdlog::debug("configuration: {}", file.string());
  } catch (const ResourceNotFound& e) {
    spdlog::warn("{}; using built-in defaults", e.what());
  }
}

const PipelineConfig& app_config() { return config_storage(); }

}  // namespace nirslam::app
