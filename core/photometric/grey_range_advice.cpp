#include "nirslam/photometric/grey_range_advice.hpp"

#include <fmt/format.h>

#include "nirslam/photometric/online_calibration.hpp"

namespace nirslam {

double exposure_factor_to_reach(const ResponseModel& response, double highest_grey, double target_grey) {
  if (!(highest_grey > 0.0) || highest_grey >= target_grey) return 1.0;
  const double now = response.inverse(highest_grey / 255.0);
  const double wanted = response.inverse(target_grey / 255.0);
  return now > 0.0 && wanted > now ? wanted / now : 1.0;
}

std::optional<GreyRangeAdvice> online_grey_range_advice(const PhotometricEstimate& estimate) {
  const bool fitted = estimate.ambiguity == AmbiguityResolution::KnownExposures ||
                      estimate.ambiguity == AmbiguityResolution::Normalisation;
  if (!fitted || estimate.model_version <= 0 || !(estimate.grey_high > estimate.grey_low) ||
      estimate.grey_high >= kOnlineAdvisedHighestGrey)
    return std::nullopt;
  return GreyRangeAdvice{estimate.grey_high, kOnlineTargetHighestGrey,
                         exposure_factor_to_reach(estimate.response, estimate.grey_high, kOnlineTargetHighestGrey)};
}

std::string describe(const GreyRangeAdvice& advice) {
  return fmt::format("the images reach grey {:.0f} at most (1 % of the samples): above it the response is extrapolated "
                     "and its scale with it; about {:.1f}x brighter images (exposure or gain) would take the brightest "
                     "surfaces near grey {:.0f} and measure it",
                     advice.highest_grey, advice.exposure_factor, advice.target_grey);
}

}  // namespace nirslam
