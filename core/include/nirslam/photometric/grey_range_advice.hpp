#pragma once
// How far up the grey scale the samples behind a fitted response reach, and how much brighter the
// images would have to be to measure the rest. With known exposures the data fix the inverse
// response G only up to the irradiance scale inside the grey range they cover; above it, and so
// the scale itself (f(1) = 1), comes from the model's continuation. A curve that bends above the
// range (a log or filmic tone curve) is then off over all levels while it fits the data exactly
// (README "Photometric calibration accuracy"). The static sweeps and the online calibration both
// give this advice, each with the levels measured for it.

#include <optional>
#include <string>

#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

struct PhotometricEstimate;

// Static sweeps (exposure_sweep_calibration.hpp): below kSweepAdvisedHighestGrey a fitted response
// is advised against as over all levels (simulated power sweeps, gamma: 101 -> 2.6 grey levels
// mean error, 138-157 -> 0.2-1.2, 166-241 -> 0.01-0.2); a sweep taken again aims its top at
// kSweepTargetHighestGrey (clipping stays rare).
inline constexpr double kSweepAdvisedHighestGrey = 180.0;
inline constexpr double kSweepTargetHighestGrey = 220.0;
// The online calibration: its sequences are judged on curves that bend near the top as well
// (the constant-radiance table's log and filmic rows: with the samples' top at 144-193 the
// response is 6-18 grey levels off over all levels, at 207-245 1.4-9), so the advice starts
// higher and aims higher.
inline constexpr double kOnlineAdvisedHighestGrey = 200.0;
inline constexpr double kOnlineTargetHighestGrey = 230.0;

// The exposure x gain factor that takes `highest_grey` to `target_grey` through `response` (exact
// up to highest_grey, the response's continuation above it); 1 when highest_grey is unknown (<= 0)
// or already at target_grey or above.
double exposure_factor_to_reach(const ResponseModel& response, double highest_grey, double target_grey);

struct GreyRangeAdvice {
  double highest_grey = 0.0;     // the 99th percentile of the fitted samples' grey values
  double target_grey = 0.0;      // where the advice aims the brightest samples
  double exposure_factor = 1.0;  // exposure_factor_to_reach
};

// The advice for an online estimate whose response the data fitted (not a given or swept one,
// nor the initial model) and whose samples stop below kOnlineAdvisedHighestGrey; nullopt otherwise.
std::optional<GreyRangeAdvice> online_grey_range_advice(const PhotometricEstimate& estimate);

// One line for an operator: what is not measured and what would measure it.
std::string describe(const GreyRangeAdvice& advice);

}  // namespace nirslam
