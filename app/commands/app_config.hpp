#pragma once

#include <filesystem>

#include "nirslam/config/pipeline_config.hpp"

namespace nirslam::app {

// The pipeline configuration of this run: `--config FILE` when given, else the shipped
// config/pipeline.yaml (found like the shaders: $NIRSLAM_CONFIG_DIR, the installed share folder,
// the source tree), else built-in defaults. main() loads it once after parsing the command line
// and before any subcommand runs; subcommands only read it. The power advisor's configuration
// (worker.illumination) comes from the shipped config/illumination.yaml, found the same way.
void load_app_config(const std::filesystem::path& explicit_file);
const PipelineConfig& app_config();
// The file `--config` named (absolute), empty when the shipped or built-in one is in use: child
// processes (bench's runs) are handed the same file.
const std::filesystem::path& app_config_file();

}  // namespace nirslam::app
