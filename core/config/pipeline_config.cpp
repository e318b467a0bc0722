#include "nirslam/config/pipeline_config.hpp"

#include <set>
#include <string>

#include <yaml-cpp/yaml.h>

#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

// Reads the keys of one YAML map, remembering which were used so leftovers can be reported.
class MapReader {
public:
  MapReader(const YAML::Node& node, std::filesystem::path file, std::string prefix)
      : node_(node), file_(std::move(file)), prefix_(std::move(prefix)) {
    if (node_ && !node_.IsMap()) fail(node_, prefix_, "expected a map of keys");
  }

  template <typename T>
  void read(const std::string& key, T& value, T min, T max) {
    used_.insert(key);
    if (!node_ || !node_[key]) return;
    const YAML::Node item = node_[key];
    T parsed{};
    try {
      parsed = item.as<T>();
    } catch (const YAML::Exception&) {
      fail(item, field(key), "expected a number, got '" + YAML::Dump(item) + "'");
    }
    if (parsed < min || parsed > max)
      fail(item, field(key), "value " + std::to_string(parsed) + " outside [" + std::to_string(min) +
                                 ", " + std::to_string(max) + "]");
    value = parsed;
  }

  void read_pacing(const std::string& key, Pacing& pacing) {
    used_.insert(key);
    if (!node_ || !node_[key]) return;
    const std::string text = node_[key].as<std::string>("");
    if (text == "fast") pacing = Pacing::AsFastAsPossible;
    else if (text == "recorded") pacing = Pacing::RecordedSpeed;
    else fail(node_[key], field(key), "expected 'fast' or 'recorded', got '" + text + "'");
  }

  void reject_unknown_keys() const {
    if (!node_) return;
    for (const auto& entry : node_) {
      const std::string key = entry.first.as<std::string>();
      if (!used_.contains(key)) fail(entry.first, field(key), "unknown key");
    }
  }

private:
  std::string field(const std::string& key) const { return prefix_.empty() ? key : prefix_ + "." + key; }

  [[noreturn]] void fail(const YAML::Node& at, const std::string& name, const std::string& message) const {
    throw InputError(file_, at.Mark().line + 1, "field '" + name + "': " + message);
  }

  YAML::Node node_;
  std::filesystem::path file_;
  std::string prefix_;
  std::set<std::string> used_;
};

}  // namespace

PipelineConfig load_pipeline_config(const std::filesystem::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::BadFile&) {
    throw InputError(file, "cannot open configuration file");
  } catch (const YAML::ParserException& e) {
    throw InputError(file, e.mark.line + 1, "not valid YAML: " + e.msg);
  }
  PipelineConfig config;
  if (root.IsNull()) return config;  // an empty file keeps every default

  if (!root.IsMap()) throw InputError(file, root.Mark().line + 1, "expected sections 'worker' and 'demo'");
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    if (key != "worker" && key != "demo")
      throw InputError(file, entry.first.Mark().line + 1, "field '" + key + "': unknown section");
  }

  MapReader worker(root["worker"], file, "worker");
  worker.read<std::size_t>("history_length", config.worker.history_length, 2, 1'000'000);
  worker.read_pacing("pacing", config.worker.pacing);
  worker.reject_unknown_keys();

  MapReader demo(root["demo"], file, "demo");
  demo.read<int>("width", config.demo.width, 64, 8192);
  demo.read<int>("height", config.demo.height, 48, 8192);
  demo.read<std::int64_t>("frames", config.demo.frame_count, 0, 100'000'000);
  demo.read<double>("fps", config.demo.fps, 0.1, 1000.0);
  demo.read<double>("illuminator_power_w", config.demo.illuminator_power_w, 0.0, 1000.0);
  demo.read<double>("exposure_ms", config.demo.exposure_ms, 0.001, 10'000.0);
  demo.read<std::uint32_t>("seed", config.demo.seed, 0, 0xffffffffu);
  demo.reject_unknown_keys();
  return config;
}

}  // namespace nirslam
