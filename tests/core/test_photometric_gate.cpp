// The gate between the photometric back end and the frames it corrects (EstimateGate,
// online_calibration.hpp; issues 6 and 8: a model that does not fit "leaves the last good
// estimate in place and says why").
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/sim/simulator.hpp"
#include "simulator_fixtures.hpp"

namespace nirslam {
namespace {

EstimateGate slope_gate() {
  EstimateGate gate;
  gate.max_response_slope = 4.0;
  gate.min_response_slope = 0.5;
  return gate;
}

TEST(PhotometricGate, PlausibleResponsesPass) {
  const EstimateGate gate = slope_gate();
  // The gamma preset's log-log slope is about 2.2 everywhere, the linear one's 1.
  EXPECT_EQ(estimate_rejection(gate, ResponseModel::from_preset(ResponsePreset::Gamma), 10.0, 220.0, 1.5), "");
  EXPECT_EQ(estimate_rejection(gate, ResponseModel::from_preset(ResponsePreset::Linear), 10.0, 220.0, 1.5), "");
  // Off by default: nothing is rejected.
  EXPECT_EQ(estimate_rejection(EstimateGate{}, ResponseModel(Eigen::Vector4d(2.0, -2.0, 1.4, -0.6)), 15.0, 220.0, 50.0), "");
}

TEST(PhotometricGate, FlatThenJumpResponseIsRejectedInsideTheObservedRange) {
  // Monotonic, but G(128) = 2.8, G(192) = 22, G(224) = 93 (grey levels): the shape the
  // illuminated mode's back end reached on the 20 W parking sequence (G(128) = 2.1, G(192) = 20,
  // G(224) = 94; truth 56 / 136 / 192), flat over the observed values and jumping at their top.
  const ResponseModel flat_then_jump(Eigen::Vector4d(2.0, -2.0, 1.4, -0.6));
  ASSERT_TRUE(flat_then_jump.is_monotonic());
  const std::string why = estimate_rejection(slope_gate(), flat_then_jump, 15.0, 220.0, 1.5);
  EXPECT_NE(why.find("response implausible"), std::string::npos) << why;
  // Outside the observed range the data say nothing, so the gate does not look there.
  EXPECT_EQ(estimate_rejection(slope_gate(), flat_then_jump, 15.0, 60.0, 1.5), "");
}

TEST(PhotometricGate, ResidualAboveTheLimitIsRejected) {
  EstimateGate gate;
  gate.max_residual_rms = 3.0;
  const ResponseModel gamma = ResponseModel::from_preset(ResponsePreset::Gamma);
  EXPECT_EQ(estimate_rejection(gate, gamma, 10.0, 220.0, 2.9), "");
  const std::string why = estimate_rejection(gate, gamma, 10.0, 220.0, 5.5);
  EXPECT_NE(why.find("residual 5.50 grey levels > 3.00"), std::string::npos) << why;
}

std::vector<Frame> small_room_frames(std::int64_t count) {
  std::vector<Frame> frames;
  for (Simulator simulator(test_sequences::small_ambient_room(count)); auto f = simulator.next();) frames.push_back(f->frame);
  return frames;
}

// Through the online calibration: a gate no fit can pass (residual limit 1e-3 grey levels)
// leaves the initial model in place for the frames and says why; the same run ungated adopts
// the back end's estimates.
TEST(PhotometricGate, RejectedEstimatesLeaveTheLastGoodModelAndSayWhy) {
  const std::vector<Frame> frames = small_room_frames(40);
  OnlineCalibrationOptions options;
  options.background_thread = false;
  const ResponseModel initial = options.backend.initial_response;
  OnlinePhotometricCalibration open(options);
  options.gate.max_residual_rms = 1e-3;
  OnlinePhotometricCalibration gated(options);
  for (const Frame& frame : frames) {
    open.process(frame);
    gated.process(frame);
  }
  const auto adopted = open.estimate();
  ASSERT_GT(adopted->model_version, 0) << adopted->status;
  EXPECT_EQ(adopted->estimates_rejected, 0);
  EXPECT_NE(adopted->response.coefficients(), initial.coefficients());

  const auto kept = gated.estimate();
  EXPECT_EQ(kept->model_version, 0) << kept->status;
  EXPECT_GT(kept->estimates_rejected, 0);
  EXPECT_EQ(kept->response.coefficients(), initial.coefficients());
  EXPECT_EQ(gated.correction_response().coefficients(), initial.coefficients());
  EXPECT_NE(kept->status.find("NOT USED, residual"), std::string::npos) << kept->status;
  EXPECT_NE(kept->status.find("last good estimate (version 0) kept"), std::string::npos) << kept->status;
}

// hold_correction (what the pipeline does while the odometry initialises): the corrected frames
// keep their model while the back end's estimates move on, and follow them once released.
TEST(PhotometricGate, HeldCorrectionKeepsItsModelUntilReleased) {
  const std::vector<Frame> frames = small_room_frames(40);
  OnlineCalibrationOptions options;
  options.background_thread = false;
  options.max_correction_step_log = 0.0;  // adopt at once, so release is visible in one frame
  const ResponseModel initial = options.backend.initial_response;
  OnlinePhotometricCalibration calibration(options);
  calibration.hold_correction(true);
  for (const Frame& frame : frames) calibration.process(frame);
  const auto estimate = calibration.estimate();
  ASSERT_GT(estimate->model_version, 0) << estimate->status;
  EXPECT_NE(estimate->response.coefficients(), initial.coefficients());
  EXPECT_EQ(calibration.correction_response().coefficients(), initial.coefficients());
  const CorrectedFrame held = calibration.process(frames.back());
  calibration.hold_correction(false);
  const CorrectedFrame released = calibration.process(frames.back());
  EXPECT_EQ(calibration.correction_response().coefficients(), calibration.estimate()->response.coefficients());
  // The same image corrected before and after: the released model changes the corrected values.
  EXPECT_GT(cv::norm(held.irradiance, released.irradiance, cv::NORM_INF), 0.1);
}

// PhotometricEstimate::response_determined, which the lamp mode's odometry waits for
// (PipelineOptions::lamp_factor_waits_for_response): a given response from the start, a fitted
// one from the first adopted update that estimated it without the lamp's factor.
TEST(PhotometricGate, TheResponseIsDeterminedWhenGivenOrOnceFittedFromExposureChanges) {
  OnlineCalibrationOptions given;
  given.background_thread = false;
  given.backend.estimate_response = false;
  EXPECT_TRUE(OnlinePhotometricCalibration(given).estimate()->response_determined);

  OnlineCalibrationOptions options;
  options.background_thread = false;
  OnlinePhotometricCalibration calibration(options);
  EXPECT_FALSE(calibration.estimate()->response_determined) << "the initial guess";
  bool determined_before_fitted = false;
  for (const Frame& frame : small_room_frames(40)) {
    calibration.process(frame);
    const auto estimate = calibration.estimate();
    determined_before_fitted |= estimate->response_determined && estimate->model_version == 0;
  }
  const auto estimate = calibration.estimate();
  ASSERT_GT(estimate->model_version, 0) << estimate->status;
  EXPECT_FALSE(determined_before_fitted);
  EXPECT_TRUE(estimate->response_determined) << estimate->status;
}

}  // namespace
}  // namespace nirslam
