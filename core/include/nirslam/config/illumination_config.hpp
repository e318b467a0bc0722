#pragma once

#include <filesystem>
#include <vector>

#include "nirslam/illumination/advisor.hpp"
#include "nirslam/illumination/exposure_check.hpp"
#include "nirslam/illumination/illuminator.hpp"

namespace nirslam {

// The powers a sweep steps through, and how many frames it averages at each.
struct SweepPlan {
  std::vector<double> powers_w{0.0, 20.0, 40.0, 50.0, 70.0, 100.0, 125.0, 150.0};
  int frames_per_power = 30;
  // Frames skipped after each power change before averaging starts (camera latency, the lamp's
  // warm-up, auto exposure settling). Frames that report their own power skip the wait.
  int settle_frames = 3;
};

// The advisor's configuration (config/illumination.yaml documents every key).
struct IlluminationConfig {
  AdvisorSettings advisor{};
  ExposureLimits exposure{};  // exposure.max_saturated_fraction is advisor.max_saturated_fraction
  SweepPlan sweep{};
  IlluminatorCapabilities illuminator{};
  std::vector<SceneType> scenes{};  // the first is the default scene
};

// Without a file: the four scene types of the paper (room, outdoor, parking, tunnel) with no prior
// ranges, and the default thresholds.
IlluminationConfig default_illumination_config();

// Reads an illumination YAML file. Keys not given keep their defaults; a `scenes` list replaces the
// default scenes. Unknown keys, wrong types, out-of-range values, duplicate scene names and priors
// with low_w > high_w throw InputError naming the file, the line and the field.
IlluminationConfig load_illumination_config(const std::filesystem::path& file);

}  // namespace nirslam
