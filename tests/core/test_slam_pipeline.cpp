// The pipeline behind the worker: which stages each mode runs, what it says when a stage cannot
// run, bad frames. Whole simulated sequences through it: whole_sequence/test_slam_pipeline_sequence.cpp.

#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/pipeline/slam_pipeline.hpp"
#include "nirslam/sim/simulator.hpp"
#include "simulator_fixtures.hpp"

namespace nirslam {
namespace {

Frame grey_frame(int width, int height, std::int64_t index) {
  Frame frame;
  frame.image = cv::Mat(height, width, CV_8UC1, cv::Scalar(90 + static_cast<int>(index % 5)));
  frame.index = index;
  frame.timestamp_s = index / 30.0;
  frame.name = "frame" + std::to_string(index) + ".png";
  return frame;
}

std::shared_ptr<const CameraModel> pinhole(int width, int height) {
  return std::make_shared<PinholeCamera>(width, height, Eigen::Vector4d(0.8 * width, 0.8 * width, width / 2.0, height / 2.0));
}

TEST(SlamPipeline, ModeNamesRoundTrip) {
  EXPECT_EQ(pipeline_modes().size(), 5u);
  for (PipelineMode mode : pipeline_modes()) EXPECT_EQ(parse_pipeline_mode(to_string(mode)), mode);
  EXPECT_FALSE(parse_pipeline_mode("dso"));
  EXPECT_EQ(parse_pipeline_mode("odometry-illuminated"), PipelineMode::OdometryIlluminated);
  // The bench order: the paper's Table 2 columns, each adding one stage.
  EXPECT_EQ(odometry_modes(),
            (std::vector<PipelineMode>{PipelineMode::Odometry, PipelineMode::Calibrated, PipelineMode::Illuminated}));
}

TEST(SlamPipeline, ModesChooseCalibrationAndTheLampFactor) {
  EXPECT_FALSE(runs_calibration(PipelineMode::Odometry));
  EXPECT_TRUE(runs_calibration(PipelineMode::Calibrated));
  EXPECT_TRUE(runs_calibration(PipelineMode::Illuminated));
  EXPECT_FALSE(runs_calibration(PipelineMode::OdometryIlluminated));
  EXPECT_FALSE(corrects_illuminator(PipelineMode::Calibrated));
  EXPECT_TRUE(corrects_illuminator(PipelineMode::Illuminated));
  EXPECT_TRUE(corrects_illuminator(PipelineMode::OdometryIlluminated));
  for (PipelineMode mode : {PipelineMode::Odometry, PipelineMode::Illuminated, PipelineMode::OdometryIlluminated}) {
    PipelineOptions options;
    options.mode = mode;
    options.calibration.background_thread = false;
    SlamPipeline pipeline(options, pinhole(64, 48));
    ASSERT_NE(pipeline.odometry(), nullptr);
    EXPECT_EQ(pipeline.odometry()->options().illuminator_correction, corrects_illuminator(mode)) << to_string(mode);
    EXPECT_EQ(pipeline.calibration() != nullptr, runs_calibration(mode)) << to_string(mode);
  }
  // The beam term only on raw frames: the calibration's halo factor holds the beam.
  PipelineOptions options;
  options.odometry.beam_exponent = 4.8;
  options.mode = PipelineMode::OdometryIlluminated;
  EXPECT_DOUBLE_EQ(SlamPipeline(options, pinhole(64, 48)).odometry()->options().beam_exponent, 4.8);
  options.mode = PipelineMode::Illuminated;
  options.calibration.background_thread = false;
  EXPECT_DOUBLE_EQ(SlamPipeline(options, pinhole(64, 48)).odometry()->options().beam_exponent, 0.0);
  // Corrected frames reach the odometry encoded with the pipeline's exponent; raw ones are taken
  // as gamma-encoded, so the lamp's factor reaches them raised to the raw frames' exponent.
  options.corrected_frame_exponent = 0.4;
  EXPECT_DOUBLE_EQ(SlamPipeline(options, pinhole(64, 48)).odometry()->options().brightness_exponent, 0.4);
  options.mode = PipelineMode::OdometryIlluminated;
  EXPECT_NEAR(SlamPipeline(options, pinhole(64, 48)).odometry()->options().brightness_exponent, 1.0 / 2.2, 1e-12);
  options.raw_frame_exponent = 0.6;
  EXPECT_DOUBLE_EQ(SlamPipeline(options, pinhole(64, 48)).odometry()->options().brightness_exponent, 0.6);
}

TEST(SlamPipeline, TheLampModeTakesItsOwnCalibrationSettings) {
  PipelineOptions options;
  options.calibration.background_thread = false;
  options.calibration.tracker.skip_coarse_levels_at_border = false;
  options.lamp_mode_track_near_border = true;
  options.calibration.tracker.min_reference_ncc = 0.7;
  options.lamp_mode_min_reference_ncc = 0.9;
  options.calibration.keyframes_follow_deformation = true;
  options.calibration.backend.vignette_rim_curvature_weight = 1.0;
  options.mode = PipelineMode::Calibrated;
  {
    const SlamPipeline calibrated(options, pinhole(64, 48));
    EXPECT_TRUE(calibrated.options().calibration.keyframes_follow_deformation);
    EXPECT_DOUBLE_EQ(calibrated.options().calibration.backend.vignette_rim_curvature_weight, 1.0);
    EXPECT_FALSE(calibrated.options().calibration.tracker.skip_coarse_levels_at_border);
    EXPECT_DOUBLE_EQ(calibrated.options().calibration.tracker.min_reference_ncc, 0.7);
    EXPECT_TRUE(calibrated.options().calibration.exposure.follow_deformation);
  }
  options.mode = PipelineMode::Illuminated;
  {
    const SlamPipeline lamp(options, pinhole(64, 48));
    EXPECT_FALSE(lamp.options().calibration.keyframes_follow_deformation);
    EXPECT_DOUBLE_EQ(lamp.options().calibration.backend.vignette_rim_curvature_weight, 0.0);
    EXPECT_TRUE(lamp.options().calibration.tracker.skip_coarse_levels_at_border);
    EXPECT_DOUBLE_EQ(lamp.options().calibration.tracker.min_reference_ncc, 0.9);
    EXPECT_FALSE(lamp.options().calibration.exposure.follow_deformation);
  }
  options.lamp_mode_keyframes_follow_surface = true;
  options.lamp_mode_vignette_rim_curvature_weight = 0.5;
  options.lamp_mode_track_near_border = false;
  options.lamp_mode_exposure_follows_surface = true;
  {
    const SlamPipeline lamp(options, pinhole(64, 48));
    EXPECT_TRUE(lamp.options().calibration.exposure.follow_deformation);
    EXPECT_TRUE(lamp.options().calibration.keyframes_follow_deformation);
    EXPECT_DOUBLE_EQ(lamp.options().calibration.backend.vignette_rim_curvature_weight, 0.5);
    EXPECT_FALSE(lamp.options().calibration.tracker.skip_coarse_levels_at_border);
  }
  // Without the lamp's distances the illuminated mode's calibration assumes constant radiance,
  // as the calibrated mode's does, and takes its settings.
  options.lamp_distances_to_calibration = false;
  options.lamp_mode_keyframes_follow_surface = false;
  const SlamPipeline constant_radiance(options, pinhole(64, 48));
  EXPECT_TRUE(constant_radiance.options().calibration.keyframes_follow_deformation);
  EXPECT_DOUBLE_EQ(constant_radiance.options().calibration.backend.vignette_rim_curvature_weight, 1.0);
  EXPECT_FALSE(constant_radiance.options().calibration.tracker.skip_coarse_levels_at_border);
}

// odometry_waits_for_model_frames: with the calibration estimating online from a linear initial
// response, the odometry's first frame is the first corrected with a model the back end fitted
// (the frames before have no odometry result), not a frame corrected with the initial guess; at 0
// it starts at once; with every estimate refused (a gate no fit passes) it starts after the wait.
TEST(SlamPipeline, TheOdometryStartsOnTheFirstFittedModel) {
  const SimulatorOptions simulated = test_sequences::small_ambient_room(24);
  std::vector<Frame> frames;
  Simulator simulator(simulated);
  while (auto f = simulator.next()) frames.push_back(f->frame);
  const auto first_odometry_frame = [&](int wait, bool refuse_all, int* model_version) {
    PipelineOptions options;
    options.mode = PipelineMode::Calibrated;
    options.calibration.background_thread = false;
    options.calibration.backend.initial_response = ResponseModel::from_preset(ResponsePreset::Linear);
    if (refuse_all) options.calibration.gate.max_residual_rms = 1e-3;
    options.odometry_waits_for_model_frames = wait;
    SlamPipeline pipeline(options, simulator.camera());
    for (const Frame& frame : frames) {
      const PipelineFrameResult result = pipeline.process(frame);
      if (result.odometry) {
        *model_version = pipeline.calibration()->correction_model_version();
        return frame.index;
      }
    }
    return std::int64_t{-1};
  };
  int version = -1;
  const std::int64_t fitted = first_odometry_frame(30, false, &version);
  EXPECT_GT(fitted, 0);
  EXPECT_GT(version, 0) << "the first odometry frame is corrected with a fitted model";
  EXPECT_EQ(first_odometry_frame(0, false, &version), 0);
  EXPECT_EQ(version, 0) << "at once: the initial model";
  EXPECT_EQ(first_odometry_frame(5, true, &version), 5) << "no fitted model: after the wait";
  EXPECT_EQ(version, 0);
}

TEST(SlamPipeline, QualityModeRunsNoStage) {
  PipelineOptions options;
  options.mode = PipelineMode::Quality;
  SlamPipeline pipeline(options, pinhole(64, 48));
  const PipelineFrameResult result = pipeline.process(grey_frame(64, 48, 0));
  EXPECT_FALSE(result.photometric);
  EXPECT_FALSE(result.odometry);
  EXPECT_TRUE(result.corrected.empty());
  EXPECT_FALSE(pipeline.photometric_view()->enabled);
  const auto trajectory = pipeline.trajectory_view();
  EXPECT_FALSE(trajectory->enabled);
  EXPECT_NE(trajectory->message.find("no odometry"), std::string::npos) << trajectory->message;
}

TEST(SlamPipeline, CalibrationAloneSaysWhenTheLampItDoesNotModelIsOn) {
  for (const PipelineMode mode : {PipelineMode::Calibrated, PipelineMode::Illuminated})
    for (const std::optional<double> power : {std::optional<double>(50.0), std::optional<double>(0.0), std::optional<double>()}) {
      PipelineOptions options;
      options.mode = mode;
      options.calibration.background_thread = false;
      SlamPipeline pipeline(options, pinhole(64, 48));
      Frame frame = grey_frame(64, 48, 0);
      frame.illuminator_power_w = power;
      pipeline.process(frame);
      const bool expected = mode == PipelineMode::Calibrated && power && *power > 0.0;
      EXPECT_EQ(pipeline.photometric_view()->lamp_not_modelled, expected)
          << to_string(mode) << ", power " << (power ? std::to_string(*power) : "not reported");
    }
}

TEST(SlamPipeline, WithoutACameraTheOdometrySaysWhyItIsOff) {
  PipelineOptions options;
  options.mode = PipelineMode::Odometry;
  SlamPipeline pipeline(options, nullptr);
  EXPECT_EQ(pipeline.odometry(), nullptr);
  EXPECT_NE(pipeline.odometry_off_reason().find("camera"), std::string::npos);
  const PipelineFrameResult result = pipeline.process(grey_frame(64, 48, 0));
  EXPECT_FALSE(result.odometry);
  EXPECT_NE(pipeline.trajectory_view()->message.find("camera"), std::string::npos);
}

// Options built in code meet the same rule as a config file's (lamp_distance_backfill_problem;
// the config's own test: PipelineConfig.LampDistanceBackfillNeedsTheTracksOwnPointAndAHeldNormal),
// in every mode, with or without a camera.
TEST(SlamPipeline, LampDistanceBackfillWithoutTheTracksOwnPointIsRefused) {
  PipelineOptions options;
  options.mode = PipelineMode::Illuminated;
  options.lamp_distance_backfill = true;
  for (const bool with_camera : {true, false}) {
    try {
      SlamPipeline pipeline(options, with_camera ? pinhole(64, 48) : nullptr);
      FAIL() << "expected an error";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("pipeline.lamp_distance_backfill"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("'neighbours'"), std::string::npos) << e.what();
    }
  }
  options.lamp_distance_source = LampDistanceSource::HeldTracks;
  options.lamp_cosine_to_calibration = true;
  options.lamp_cosine_held_per_track = false;
  EXPECT_THROW(SlamPipeline(options, pinhole(64, 48)), std::invalid_argument);
  options.lamp_cosine_held_per_track = true;
  EXPECT_FALSE(lamp_distance_backfill_problem(options));
  const SlamPipeline pipeline(options, pinhole(64, 48));
  EXPECT_NE(pipeline.odometry(), nullptr);
}

TEST(SlamPipeline, FrameOfTheWrongSizeIsNamed) {
  PipelineOptions options;
  options.mode = PipelineMode::Odometry;
  SlamPipeline pipeline(options, pinhole(64, 48));
  try {
    pipeline.process(grey_frame(80, 48, 7));
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("frame7.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("80x48"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nirslam
