#include "commands/app_config.hpp"

#include <spdlog/spdlog.h>

#include "nirslam/common/resource_paths.hpp"
#include "nirslam/config/illumination_config.hpp"

namespace nirslam::app {
namespace {

PipelineConfig& config_storage() {
  static PipelineConfig config;
  return config;
}

std::filesystem::path& explicit_file_storage() {
  static std::filesystem::path file;
  return file;
}

}  // namespace

namespace {

// The advisor's configuration: the shipped config/illumination.yaml (scene priors, thresholds,
// sweep plan), else built-in defaults without priors. A file that exists must load.
IlluminationConfig load_shipped_illumination_config() {
  try {
    const auto file = find_resource_dir(kConfigFolder) / "illumination.yaml";
    std::error_code error;
    if (std::filesystem::is_regular_file(file, error)) {
      spdlog::debug("illumination configuration: {}", file.string());
      return load_illumination_config(file);
    }
    spdlog::warn("{} not found; the power advisor has no scene priors", file.string());
  } catch (const ResourceNotFound& e) {
    spdlog::warn("{}; the power advisor has no scene priors", e.what());
  }
  return default_illumination_config();
}

}  // namespace

void load_app_config(const std::filesystem::path& explicit_file) {
  explicit_file_storage() = explicit_file.empty() ? explicit_file : std::filesystem::absolute(explicit_file);
  if (!explicit_file.empty()) {
    config_storage() = load_pipeline_config(explicit_file);  // a file asked for must load
    spdlog::debug("configuration: {}", explicit_file.string());
  } else {
    try {
      const auto file = find_resource_dir(kConfigFolder) / "pipeline.yaml";
      config_storage() = load_pipeline_config(file);
      spdlog::debug("configuration: {}", file.string());
    } catch (const ResourceNotFound& e) {
      spdlog::warn("{}; using built-in defaults", e.what());
    }
  }
  config_storage().worker.illumination = load_shipped_illumination_config();
}

const PipelineConfig& app_config() { return config_storage(); }

const std::filesystem::path& app_config_file() { return explicit_file_storage(); }

}  // namespace nirslam::app
