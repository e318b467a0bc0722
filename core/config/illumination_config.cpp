#include "nirslam/config/illumination_config.hpp"

#include <algorithm>
#include <string>

#include <yaml-cpp/yaml.h>

#include "nirslam/common/error.hpp"
#include "yaml_map_reader.hpp"

namespace nirslam {
using config_detail::load_yaml_file;
using config_detail::YamlMapReader;

IlluminationConfig default_illumination_config() {
  IlluminationConfig config;
  config.scenes = {
      {"room", "Indoor room", {"indoor"}, std::nullopt},
      {"outdoor", "Outdoor at night", {}, std::nullopt},
      {"parking", "Underground parking", {"underground"}, std::nullopt},
      {"tunnel", "Pipe tunnel", {"pipe"}, std::nullopt},
  };
  return config;
}

namespace {

SceneType read_scene(const YAML::Node& node, const std::filesystem::path& file, const std::string& prefix) {
  if (!node.IsMap()) throw InputError(file, node.Mark().line + 1, "field '" + prefix + "': expected a map of keys");
  YamlMapReader reader(node, file, prefix);
  SceneType scene;
  const auto name = reader.read_text("name");
  if (!name || name->empty()) reader.fail_at("name", "every scene needs a name");
  scene.name = *name;
  scene.label = reader.read_text("label").value_or(scene.name);
  reader.read_text_list("aliases", scene.aliases);
  if (const YAML::Node prior_node = reader.child("prior"); prior_node) {
    YamlMapReader prior(prior_node, file, reader.field("prior"));
    PowerPrior p;
    if (!prior.has("low_w") || !prior.has("high_w")) prior.fail_at("low_w", "a prior needs low_w and high_w");
    prior.read<double>("low_w", p.low_w, 0.0, 10'000.0);
    prior.read<double>("high_w", p.high_w, 0.0, 10'000.0);
    if (p.high_w < p.low_w) prior.fail_at("high_w", "high_w is below low_w");
    const auto basis = prior.read_text("basis");
    if (!basis) prior.fail_at("basis", "say where the range comes from: 'paper' or 'assumption'");
    if (*basis == "paper") p.basis = PriorBasis::Paper;
    else if (*basis == "assumption") p.basis = PriorBasis::Assumption;
    else prior.fail_at("basis", "expected 'paper' or 'assumption', got '" + *basis + "'");
    p.note = prior.read_text("note").value_or("");
    prior.reject_unknown_keys();
    scene.prior = p;
  }
  reader.reject_unknown_keys();
  return scene;
}

}  // namespace

IlluminationConfig load_illumination_config(const std::filesystem::path& file) {
  const YAML::Node root = load_yaml_file(file);
  IlluminationConfig config = default_illumination_config();
  if (root.IsNull()) return config;
  YamlMapReader top(root, file, "");

  YamlMapReader advisor(top.child("advisor"), file, "advisor");
  advisor.read<double>("plateau_share", config.advisor.plateau_share, 0.5, 0.9999);
  advisor.read<double>("max_saturated_fraction", config.advisor.max_saturated_fraction, 0.0, 1.0);
  advisor.read<int>("min_sweep_points", config.advisor.min_sweep_points, 3, 1000);
  advisor.read<double>("min_rise_bits", config.advisor.min_rise_bits, 0.0, 8.0);
  advisor.reject_unknown_keys();
  config.exposure.max_saturated_fraction = config.advisor.max_saturated_fraction;

  YamlMapReader warnings(top.child("warnings"), file, "warnings");
  warnings.read<double>("dark_mean", config.exposure.dark_mean, 0.0, 1.0);
  warnings.read<double>("dark_black_fraction", config.exposure.dark_black_fraction, 0.0, 1.0);
  warnings.reject_unknown_keys();

  YamlMapReader illuminator(top.child("illuminator"), file, "illuminator");
  illuminator.read<double>("min_power_w", config.illuminator.min_power_w, 0.0, 10'000.0);
  illuminator.read<double>("max_power_w", config.illuminator.max_power_w, 0.0, 10'000.0);
  illuminator.read<double>("step_w", config.illuminator.step_w, 0.0, 1'000.0);
  if (config.illuminator.max_power_w <= config.illuminator.min_power_w)
    illuminator.fail_at("max_power_w", "max_power_w must exceed min_power_w");
  illuminator.reject_unknown_keys();

  YamlMapReader sweep(top.child("sweep"), file, "sweep");
  sweep.read_list<double>("powers_w", config.sweep.powers_w, config.illuminator.min_power_w,
                          config.illuminator.max_power_w);
  if (config.sweep.powers_w.empty()) sweep.fail_at("powers_w", "needs at least one power");
  sweep.read<int>("frames_per_power", config.sweep.frames_per_power, 1, 100'000);
  sweep.read<int>("settle_frames", config.sweep.settle_frames, 0, 10'000);
  sweep.reject_unknown_keys();

  if (const YAML::Node scenes = top.child("scenes"); scenes) {
    if (!scenes.IsSequence() || scenes.size() == 0)
      throw InputError(file, scenes.Mark().line + 1, "field 'scenes': expected a list of scenes");
    config.scenes.clear();
    for (std::size_t i = 0; i < scenes.size(); ++i) {
      const std::string prefix = "scenes[" + std::to_string(i) + "]";
      SceneType scene = read_scene(scenes[i], file, prefix);
      std::vector<std::string> names = scene.aliases;
      names.push_back(scene.name);
      for (const std::string& n : names)
        if (find_scene(config.scenes, n) != nullptr)
          throw InputError(file, scenes[i].Mark().line + 1,
                           "field '" + prefix + "': the name '" + n + "' is used by an earlier scene");
      config.scenes.push_back(std::move(scene));
    }
  }
  top.reject_unknown_keys();
  return config;
}

}  // namespace nirslam
