#include "nirslam/config/pipeline_config.hpp"

#include <string>

#include <yaml-cpp/yaml.h>

#include "yaml_map_reader.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
using config_detail::load_yaml_file;
using config_detail::YamlMapReader;

PipelineConfig load_pipeline_config(const std::filesystem::path& file) {
  const YAML::Node root = load_yaml_file(file);
  PipelineConfig config;
  if (root.IsNull()) return config;  // an empty file keeps every default

  if (!root.IsMap()) throw InputError(file, root.Mark().line + 1, "expected sections 'worker' and 'demo'");
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    if (key != "worker" && key != "demo")
      throw InputError(file, entry.first.Mark().line + 1, "field '" + key + "': unknown section");
  }

  YamlMapReader worker(root["worker"], file, "worker");
  worker.read<std::size_t>("history_length", config.worker.history_length, 2, 1'000'000);
  if (const auto pacing = worker.read_text("pacing")) {
    if (*pacing == "fast") config.worker.pacing = Pacing::AsFastAsPossible;
    else if (*pacing == "recorded") config.worker.pacing = Pacing::RecordedSpeed;
    else worker.fail_at("pacing", "expected 'fast' or 'recorded', got '" + *pacing + "'");
  }
  worker.reject_unknown_keys();

  YamlMapReader demo(root["demo"], file, "demo");
  demo.read<int>("width", config.demo.width, 64, 8192);
  demo.read<int>("height", config.demo.height, 48, 8192);
  demo.read<std::int64_t>("frames", config.demo.frame_count, 0, 100'000'000);
  demo.read<double>("fps", config.demo.fps, 0.1, 1000.0);
  demo.read<double>("illuminator_power_w", config.demo.illuminator_power_w, 0.0, 150.0);
  demo.read<double>("exposure_ms", config.demo.exposure_ms, 0.001, 10'000.0);
  demo.read<std::uint32_t>("seed", config.demo.seed, 0, 0xffffffffu);
  demo.reject_unknown_keys();
  return config;
}

}  // namespace nirslam
