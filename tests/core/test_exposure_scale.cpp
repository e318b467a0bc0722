#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "nirslam/photometric/calibration_output.hpp"
#include "nirslam/photometric/exposure_scale.hpp"

namespace nirslam {
namespace {

// A chain that took its scale from a first frame it got 7 % wrong (the auto exposure's ramp),
// then followed every later ratio within +-1 %: the reported scale from the median puts the
// typical frame right and keeps every ratio.
std::vector<ExposureSample> ramp_history() {
  std::vector<ExposureSample> history;
  for (int i = 0; i < 60; ++i) {
    const double truth = i < 10 ? 2.0 * std::pow(1.3, i) : 2.0 * std::pow(1.3, 10);
    const double ramp_error = i < 10 ? 1.0 - 0.007 * i : 0.93;       // estimate / truth
    const double noise = 1.0 + 0.01 * std::sin(1.7 * i);             // the chain's own +-1 %
    ExposureSample s;
    s.frame_index = 100 + i;
    s.reported = truth;
    s.estimated = truth * ramp_error * noise;
    s.status = i == 0 ? ExposureStatus::FirstFrame : ExposureStatus::Estimated;
    if (i == 0) s.estimated = truth;
    history.push_back(s);
  }
  return history;
}

TEST(ReportedExposureScale, TheMedianFramePutsTheChainOnTheReportedScale) {
  const std::vector<ExposureSample> history = ramp_history();
  const ReportedExposureScale scale = reported_exposure_scale(history);
  EXPECT_EQ(scale.frames, 59);  // the first frame (= reported by construction) left out
  EXPECT_NEAR(scale.factor, 1.0 / 0.93, 0.006);
  int within_two_percent = 0;  // the chain's +-1 % and the median's own offset
  for (const ExposureSample& s : history)
    within_two_percent += std::abs(*s.estimated * scale.factor / *s.reported - 1.0) < 0.02;
  EXPECT_GE(within_two_percent, 50);  // the 50 frames after the ramp (the ramp's: up to 7 %)
}

TEST(ReportedExposureScale, WithoutReportedExposuresNothingChanges) {
  std::vector<ExposureSample> history = ramp_history();
  for (ExposureSample& s : history) s.reported.reset();
  history[3].estimated.reset();  // a kept frame has no estimate: left out, no failure
  const ReportedExposureScale scale = reported_exposure_scale(history);
  EXPECT_EQ(scale.frames, 0);
  EXPECT_EQ(scale.factor, 1.0);
}

TEST(ReportedExposureScale, RestartsAndNonFiniteValuesAreLeftOut) {
  std::vector<ExposureSample> history = ramp_history();
  for (int i = 20; i < 50; ++i) history[static_cast<std::size_t>(i)].status = ExposureStatus::Restarted;
  history[55].estimated = std::nan("");
  history[56].reported = 0.0;
  const ReportedExposureScale scale = reported_exposure_scale(history);
  EXPECT_EQ(scale.frames, 59 - 30 - 2);
  EXPECT_NEAR(scale.factor, 1.0 / 0.93, 0.006);
}

// The running median of a live chain equals the batch one at every length, odd and even.
TEST(ReportedExposureScale, TheRunningMedianIsTheMedianAtEveryFrame) {
  std::vector<ExposureSample> history;
  ReportedExposureScaleTracker tracker;
  std::vector<double> log_ratios;
  for (int i = 0; i < 41; ++i) {
    ExposureSample s;
    s.frame_index = i;
    s.status = ExposureStatus::Estimated;
    s.reported = 10.0;
    s.estimated = 10.0 * std::exp(0.05 * std::sin(2.3 * i) + 0.01 * (i % 7));
    history.push_back(s);
    tracker.add(s);
    log_ratios.push_back(std::log(*s.reported / *s.estimated));
    std::vector<double> sorted = log_ratios;
    std::sort(sorted.begin(), sorted.end());
    const std::size_t n = sorted.size();
    const double median = n % 2 == 1 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
    EXPECT_NEAR(tracker.current().factor, std::exp(median), 1e-12) << i;
    EXPECT_EQ(tracker.current().frames, static_cast<int>(n));
    EXPECT_NEAR(reported_exposure_scale(history).factor, std::exp(median), 1e-12) << i;
  }
  tracker.reset();
  EXPECT_EQ(tracker.current().frames, 0);
  EXPECT_EQ(tracker.current().factor, 1.0);
}

// The output and the comparison with ground truth use the reported scale: times.txt and the
// errors say the same thing, and the error is the typical frame's, not the first's.
TEST(ReportedExposureScale, TimesAndErrorsAreOnTheReportedScale) {
  const std::vector<ExposureSample> history = ramp_history();
  PhotometricGroundTruth truth;
  for (const ExposureSample& s : history) truth.exposures.emplace_back(s.frame_index, *s.reported);
  const PhotometricErrors errors = compare_with_ground_truth(truth.response, truth.vignette, history, truth, 64, 48);
  EXPECT_LT(errors.exposure_median_relative, 0.015);
  EXPECT_LT(errors.exposure_median_relative_aligned, 0.015);
  EXPECT_GT(errors.exposure_max_relative, 0.06);  // the first frames, where the chain's ramp error lies
  EXPECT_LT(errors.exposure_max_relative, 0.09);
  // Without reported exposures: the first frame's scale, so the ramp's 7 % on every later frame.
  std::vector<ExposureSample> relative = history;
  for (ExposureSample& s : relative) s.reported.reset();
  const PhotometricErrors first = compare_with_ground_truth(truth.response, truth.vignette, relative, truth, 64, 48);
  EXPECT_GT(first.exposure_median_relative, 0.06);
  EXPECT_LT(first.exposure_median_relative_aligned, 0.015);  // the ratios themselves are right

  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "nirslam_exposure_scale_test";
  std::filesystem::remove_all(dir);
  PhotometricEstimate estimate;
  CalibrationOutputInfo info;
  info.width = 64;
  info.height = 48;
  write_calibration_output(dir, estimate, history, info, errors);
  std::ifstream times(dir / "times.txt");
  std::string index;
  double timestamp = 0.0, exposure = 0.0;
  const double factor = reported_exposure_scale(history).factor;
  for (const ExposureSample& s : history) {
    ASSERT_TRUE(times >> index >> timestamp >> exposure);
    EXPECT_NEAR(exposure, *s.estimated * factor, 1e-5);
  }
  std::ifstream json_file(dir / "calibration.json");
  const nlohmann::json j = nlohmann::json::parse(json_file);
  EXPECT_NEAR(j["exposure_scale"]["factor"].get<double>(), factor, 1e-12);
  EXPECT_EQ(j["exposure_scale"]["frames"].get<int>(), 59);
  EXPECT_NEAR(j["exposures"][30]["exposure_estimated"].get<double>(), *history[30].estimated * factor, 1e-9);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace nirslam
