#pragma once

// The illuminator power advisor. With a sweep of the scene it fits the entropy curve
// (saturation_curve.hpp) and recommends the lowest power whose fitted entropy reaches a share of
// the plateau (default 98 %) without more than a set share of saturated pixels; with no usable sweep
// it falls back to the scene type's prior range (config/illumination.yaml). Every recommendation
// carries its reasons as numbers and a confidence.

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "nirslam/illumination/illuminator.hpp"
#include "nirslam/illumination/saturation_curve.hpp"
#include "nirslam/illumination/sweep.hpp"

namespace nirslam {

struct AdvisorSettings {
  double plateau_share = 0.98;           // of the fitted plateau entropy H_max, in (0, 1)
  double max_saturated_fraction = 0.01;  // saturated (clipped-high) pixels allowed at the recommended power
  int min_sweep_points = 4;              // fewer distinct powers: the prior stands
  // A sweep whose entropies span less than this has no rise to fit: the lamp adds nothing the
  // camera can see (ambient light dominates, or the lamp does not reach the scene).
  double min_rise_bits = 0.1;
};

// Where a prior range comes from. Only Paper ranges are the paper's; the others are the project's
// and say so wherever they are shown.
enum class PriorBasis { Paper, Assumption };
const char* to_string(PriorBasis basis);

struct PowerPrior {
  double low_w = 0.0;
  double high_w = 0.0;
  PriorBasis basis = PriorBasis::Assumption;
  std::string note;  // the source, in words
  double centre_w() const { return 0.5 * (low_w + high_w); }
};

// A type of scene the operator can pick (config/illumination.yaml `scenes`).
struct SceneType {
  std::string name;                  // "room"
  std::string label;                 // "Indoor room"
  std::vector<std::string> aliases{};  // "indoor"
  std::optional<PowerPrior> prior{};
};

// The scene named `name` or one of its aliases (any case); nullptr when none matches.
const SceneType* find_scene(std::span<const SceneType> scenes, std::string_view name);

enum class RecommendationSource { None, Prior, Sweep };
enum class Confidence { None, Low, Medium, High };
const char* to_string(RecommendationSource source);
const char* to_string(Confidence confidence);

struct Recommendation {
  RecommendationSource source = RecommendationSource::None;
  double power_w = 0.0;
  // Sweep: power_w -/+ one standard deviation from the fit's covariance (when known); prior: its range.
  std::optional<double> low_w{};
  std::optional<double> high_w{};
  Confidence confidence = Confidence::None;

  // Sweep only.
  std::optional<SaturationFit> fit{};
  int points_fitted = 0;
  std::vector<double> excluded_powers_w{};  // past the entropy peak (entropy falling as pixels clip)
  double share_power_w = 0.0;    // where the fitted curve reaches the share of its plateau
  double expected_entropy_bits = 0.0;       // fitted entropy at power_w
  double expected_share = 0.0;              // expected_entropy_bits / H_max
  std::optional<double> expected_saturated_fraction{};  // interpolated from the sweep (unknown beyond it)
  double highest_swept_w = 0.0;
  bool plateau_reached = false;  // the sweep went at least as far as share_power_w
  bool extrapolated = false;     // power_w lies beyond the highest swept power
  bool clipping_limited = false; // the saturation limit, not the plateau, set power_w
  bool controller_limited = false;  // the illuminator's maximum set power_w

  std::vector<std::string> reasons{};  // sentences with the numbers behind the recommendation
  std::string headline() const;      // e.g. "62 W (sweep, high confidence)"
};

// The recommendation from a sweep's points. Source None (with the reason) when fewer than
// settings.min_sweep_points distinct powers were measured.
Recommendation recommend_from_sweep(std::span<const SweepPoint> points, const AdvisorSettings& settings,
                                    const IlluminatorCapabilities& illuminator);

// The recommendation from a scene's prior: its range's centre, low confidence. Source None when
// the scene has no prior.
Recommendation recommend_from_prior(const SceneType& scene, const IlluminatorCapabilities& illuminator);

// The sweep's recommendation as soon as it has one, else the prior's (the sweep's reasons for not
// recommending yet are kept in the reasons).
Recommendation advise(std::span<const SweepPoint> points, const SceneType* scene, const AdvisorSettings& settings,
                      const IlluminatorCapabilities& illuminator);

}  // namespace nirslam
