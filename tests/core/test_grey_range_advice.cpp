// The advice when a fitted response's samples stop short of the top of the grey scale: how much
// brighter the images would have to be, and for which estimates it is given at all.
#include <gtest/gtest.h>

#include "nirslam/photometric/grey_range_advice.hpp"
#include "nirslam/photometric/online_calibration.hpp"

namespace nirslam {
namespace {

PhotometricEstimate fitted_estimate(ResponsePreset preset, double grey_high) {
  PhotometricEstimate estimate;
  estimate.response = ResponseModel::from_preset(preset);
  estimate.model_version = 3;
  estimate.ambiguity = AmbiguityResolution::KnownExposures;
  estimate.grey_low = 12.0;
  estimate.grey_high = grey_high;
  return estimate;
}

TEST(GreyRangeAdvice, TheFactorTakesTheBrightestSamplesToTheTargetThroughTheResponse) {
  // A linear response: grey is proportional to exposure, so 110 -> 220 is exactly 2x.
  EXPECT_NEAR(exposure_factor_to_reach(ResponseModel::from_preset(ResponsePreset::Linear), 110.0, 220.0), 2.0, 1e-3);
  // Through a curved response the factor is the ratio of the irradiances at the two grey levels.
  const ResponseModel log = ResponseModel::from_preset(ResponsePreset::Log);
  const double factor = exposure_factor_to_reach(log, 144.0, kOnlineTargetHighestGrey);
  EXPECT_NEAR(factor, log.inverse(kOnlineTargetHighestGrey / 255.0) / log.inverse(144.0 / 255.0), 1e-9);
  EXPECT_GT(factor, kOnlineTargetHighestGrey / 144.0) << "a compressive curve needs more than the grey ratio";
  EXPECT_NEAR(255.0 * log(factor * log.inverse(144.0 / 255.0)), kOnlineTargetHighestGrey, 1e-6);
  // Samples at the target already, or no samples, need nothing.
  EXPECT_EQ(exposure_factor_to_reach(log, 225.0, 220.0), 1.0);
  EXPECT_EQ(exposure_factor_to_reach(log, 0.0, 220.0), 1.0);
}

TEST(GreyRangeAdvice, IsGivenOnlyForAFittedResponseWhoseSamplesStopShort) {
  const auto advice = online_grey_range_advice(fitted_estimate(ResponsePreset::Log, 144.0));
  ASSERT_TRUE(advice.has_value());
  EXPECT_EQ(advice->highest_grey, 144.0);
  EXPECT_EQ(advice->target_grey, kOnlineTargetHighestGrey);
  EXPECT_GT(advice->exposure_factor, 1.5);
  const std::string text = describe(*advice);
  EXPECT_NE(text.find("grey 144"), std::string::npos) << text;
  EXPECT_NE(text.find("extrapolated"), std::string::npos) << text;

  // Without reported exposures the response is fitted too (the gamma by the normalisation).
  PhotometricEstimate relative = fitted_estimate(ResponsePreset::Log, 144.0);
  relative.ambiguity = AmbiguityResolution::Normalisation;
  EXPECT_TRUE(online_grey_range_advice(relative).has_value());

  EXPECT_TRUE(online_grey_range_advice(fitted_estimate(ResponsePreset::Log, kOnlineAdvisedHighestGrey - 1.0)));
  EXPECT_FALSE(online_grey_range_advice(fitted_estimate(ResponsePreset::Log, kOnlineAdvisedHighestGrey))) << "reaches the top";
  PhotometricEstimate initial = fitted_estimate(ResponsePreset::Log, 144.0);
  initial.model_version = 0;
  EXPECT_FALSE(online_grey_range_advice(initial)) << "no back-end estimate yet";
  PhotometricEstimate unknown = fitted_estimate(ResponsePreset::Log, 0.0);
  unknown.grey_low = 0.0;
  EXPECT_FALSE(online_grey_range_advice(unknown)) << "no observed range";
  for (const AmbiguityResolution held : {AmbiguityResolution::PowerSweep, AmbiguityResolution::Given}) {
    PhotometricEstimate estimate = fitted_estimate(ResponsePreset::Log, 144.0);
    estimate.ambiguity = held;
    EXPECT_FALSE(online_grey_range_advice(estimate)) << "the response is held, not fitted: " << to_string(held);
  }
}

}  // namespace
}  // namespace nirslam
