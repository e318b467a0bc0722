#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "commands/app_config.hpp"
#include "commands/subcommand.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/config/illumination_config.hpp"
#include "nirslam/illumination/advisor.hpp"
#include "nirslam/illumination/sweep_folder.hpp"
#include "nirslam/quality/frame_metrics.hpp"

namespace nirslam::app {
namespace {

struct AdviseOptions {
  std::vector<std::filesystem::path> folders;
  std::string scene;
  std::optional<double> share;
  std::optional<double> max_clipped;
  std::filesystem::path illumination_config;
  bool markdown = false;
};

// One scene's sweep and what the advisor made of it.
struct Result {
  std::filesystem::path folder;
  std::string scene_label;
  SweepRecord sweep;
  Recommendation recommendation;
};

// RMS gradient in 8-bit grey levels per pixel: what an image person reads as sharpness.
double rms_gradient_grey_levels(double gradient_energy) { return 255.0 * std::sqrt(std::max(0.0, gradient_energy)); }

void print_points(const SweepRecord& sweep) {
  std::printf("  %7s %6s %14s %10s %7s %6s %9s %9s %9s %9s %9s\n", "power", "frames", "entropy", "saturated", "black",
              "mean", "contrast", "sharpness", "features", "coverage", "evenness");
  std::printf("  %7s %6s %14s %10s %7s %6s %9s %9s %9s %9s %9s\n", "[W]", "", "[bit]", "[%]", "[%]", "[%]", "[%]",
              "[gl/px]", "", "[%]", "[0-1]");
  for (const SweepPoint& p : sweep.points()) {
    const std::string entropy = fmt::format("{:.3f} ±{:.3f}", p.entropy_bits.mean, p.entropy_bits.stddev());
    std::printf("  %7.1f %6d %14s %10.2f %7.2f %6.1f %9.2f %9.2f %9.0f %9.1f %9.3f\n", p.power_w, p.frames,
                entropy.c_str(), 100.0 * p.saturated_fraction.mean, 100.0 * p.black_fraction.mean,
                100.0 * p.mean.mean, 100.0 * p.rms_contrast.mean, rms_gradient_grey_levels(p.gradient_energy.mean),
                p.feature_count.mean, 100.0 * p.coverage.mean, p.evenness.mean);
  }
}

void print_recommendation(const Recommendation& r) {
  std::printf("  Recommended: %s\n", r.headline().c_str());
  for (const std::string& reason : r.reasons) std::printf("    - %s\n", reason.c_str());
}

// Entropy by power, scenes as rows: the layout of the paper's Table 1.
void print_table(const std::vector<Result>& results, bool markdown) {
  std::vector<double> powers;
  for (const Result& r : results)
    for (const SweepPoint& p : r.sweep.points())
      if (std::none_of(powers.begin(), powers.end(),
                       [&](double w) { return std::abs(w - p.power_w) <= SweepRecord::kSamePowerW; }))
        powers.push_back(p.power_w);
  std::sort(powers.begin(), powers.end());
  const auto power_label = [](double w) { return fmt::format("{:g} W", w); };
  const auto recommendation = [](const Recommendation& r) {
    if (r.source == RecommendationSource::None) return std::string("none");
    return fmt::format("{:.0f} W ({}{}, {})", r.power_w, to_string(r.source), r.extrapolated ? ", extrapolated" : "",
                       to_string(r.confidence));
  };
  std::printf("\nEntropy [bit] by illuminator power (the paper's Table 1 layout)\n");
  if (markdown) {
    std::printf("| Scene |");
    for (double w : powers) std::printf(" %s |", power_label(w).c_str());
    std::printf(" Recommended |\n|---|");
    for (std::size_t i = 0; i < powers.size(); ++i) std::printf("---:|");
    std::printf("---|\n");
    for (const Result& r : results) {
      std::printf("| %s |", r.scene_label.c_str());
      for (double w : powers) {
        const SweepPoint* p = r.sweep.find(w);
        std::printf(" %s |", p ? fmt::format("{:.2f}", p->entropy_bits.mean).c_str() : "–");
      }
      std::printf(" %s |\n", recommendation(r.recommendation).c_str());
    }
    return;
  }
  std::printf("  %-22s", "scene");
  for (double w : powers) std::printf(" %7s", power_label(w).c_str());
  std::printf("   recommended\n");
  for (const Result& r : results) {
    std::printf("  %-22s", r.scene_label.c_str());
    for (double w : powers) {
      const SweepPoint* p = r.sweep.find(w);
      std::printf(" %7s", p ? fmt::format("{:.2f}", p->entropy_bits.mean).c_str() : "–");
    }
    std::printf("   %s\n", recommendation(r.recommendation).c_str());
  }
}

int run_advise(const AdviseOptions& options) {
  IlluminationConfig config = options.illumination_config.empty() ? app_config().worker.illumination
                                                                   : load_illumination_config(options.illumination_config);
  if (options.share) config.advisor.plateau_share = *options.share;
  if (options.max_clipped) config.advisor.max_saturated_fraction = *options.max_clipped;
  const SceneType* forced_scene = nullptr;
  if (!options.scene.empty()) {
    forced_scene = find_scene(config.scenes, options.scene);
    if (forced_scene == nullptr) {
      std::string names;
      for (const SceneType& s : config.scenes) names += (names.empty() ? "" : ", ") + s.name;
      throw std::invalid_argument("--scene: unknown scene '" + options.scene + "' (" + names + ")");
    }
  }

  QualityMeter meter;
  std::vector<Result> results;
  for (const auto& folder : options.folders) {
    const SweepFolder sweep_folder = read_sweep_folder(folder);
    // The scene: --scene, else the table's column, else the simulator's groundtruth.json.
    std::string default_scene = forced_scene ? forced_scene->name : sweep_folder.ground_truth_scene.value_or("");
    SweepFolder measured = sweep_folder;
    if (forced_scene)
      for (SweepImage& image : measured.images) image.scene.clear();
    for (auto& [scene_name, record] : measure_sweep(measured, meter, default_scene)) {
      const SceneType* scene = scene_name.empty() ? nullptr : find_scene(config.scenes, scene_name);
      if (!scene_name.empty() && scene == nullptr)
        throw InputError(sweep_folder.table, "scene '" + scene_name + "' is not a scene type of the configuration");
      Result result;
      result.folder = folder;
      result.scene_label = scene ? scene->label : std::string("(scene not given)");
      result.recommendation = advise(record.points(), scene, config.advisor, config.illuminator);
      result.sweep = std::move(record);
      results.push_back(std::move(result));
    }
  }

  std::printf("Illuminator power advice: plateau share %.0f %%, at most %.2f %% saturated pixels\n",
              100.0 * config.advisor.plateau_share, 100.0 * config.advisor.max_saturated_fraction);
  for (const Result& r : results) {
    int frames = 0;
    for (const SweepPoint& p : r.sweep.points()) frames += p.frames;
    std::printf("\n%s · %s · %zu powers, %d images\n", r.folder.string().c_str(), r.scene_label.c_str(),
                r.sweep.points().size(), frames);
    print_points(r.sweep);
    print_recommendation(r.recommendation);
  }
  print_table(results, options.markdown);
  return 0;
}

}  // namespace

void add_advise_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<AdviseOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "advise",
      "Recommend an illuminator power from power sweeps: per folder, the metrics per power (entropy, clipping, mean,\n"
      "contrast, sharpness, FAST corners and their coverage), the fitted entropy curve H(P) = H_max - (H_max - H_0)\n"
      "exp(-P / P_s) and the lowest power reaching a share of its plateau within the clipping limit, with reasons\n"
      "and confidence; then the entropy table of all folders in the layout of the paper's Table 1.\n"
      "A sweep folder holds images and sweep.csv: a header naming the columns 'file' (relative to the folder) and\n"
      "'power_w', optionally 'scene'; other columns are ignored (`nirslam simulate --sweep` writes such folders).");
  cmd->add_option("sweep_dirs", options->folders, "Sweep folders (each with sweep.csv)")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--scene", options->scene,
                  "Scene type of every image (room, outdoor, parking, tunnel or an alias); default: the 'scene' "
                  "column, else the simulator's groundtruth.json");
  cmd->add_option("--share", options->share, "Share of the entropy plateau to reach (default 0.98, config/illumination.yaml)")
      ->check(CLI::Range(0.5, 0.9999));
  cmd->add_option("--max-clipped", options->max_clipped,
                  "Largest share of saturated pixels allowed at the recommended power (default 0.01)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--illumination-config", options->illumination_config,
                  "Advisor configuration (YAML); default: the shipped config/illumination.yaml")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--markdown", options->markdown, "Print the entropy table as a Markdown table");
  cmd->callback([options, &action] { action = [options] { return run_advise(*options); }; });
}

}  // namespace nirslam::app
