#pragma once

#include <filesystem>

#include "nirslam/sources/demo_source.hpp"
#include "nirslam/worker/worker.hpp"

namespace nirslam {

struct PipelineConfig {
  WorkerOptions worker;
  DemoOptions demo;
};

// Reads a pipeline YAML file (config/pipeline.yaml documents every key). Keys not given keep their
// defaults. Unknown keys, wrong types and out-of-range values throw InputError naming the file,
// the line and the field.
PipelineConfig load_pipeline_config(const std::filesystem::path& file);

}  // namespace nirslam
