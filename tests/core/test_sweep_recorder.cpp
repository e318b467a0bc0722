// Sweep records (running statistics per power) and the sweep wizard's state machine, fed frame
// metrics as the worker would feed them.

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/illumination/sweep_recorder.hpp"

namespace nirslam {
namespace {

FrameMetrics metrics_with_entropy(double bits, double saturated = 0.0) {
  FrameMetrics m;
  m.quality.entropy_bits = bits;
  m.quality.saturated_fraction = saturated;
  m.quality.mean = 0.3;
  m.structure.feature_count = 100;
  return m;
}

TEST(RunningStats, MatchesTwoPassMeanAndSampleDeviation) {
  const std::vector<double> values{6.1, 6.4, 5.9, 6.3, 6.0, 6.2};
  RunningStats stats;
  for (double v : values) stats.add(v);
  double mean = 0.0;
  for (double v : values) mean += v / values.size();
  double ss = 0.0;
  for (double v : values) ss += (v - mean) * (v - mean);
  EXPECT_EQ(stats.count, 6);
  EXPECT_NEAR(stats.mean, mean, 1e-15);
  EXPECT_NEAR(stats.stddev(), std::sqrt(ss / 5.0), 1e-15);
  EXPECT_DOUBLE_EQ(RunningStats{}.stddev(), 0.0);
}

TEST(SweepRecord, GroupsFramesByPowerInAscendingOrder) {
  SweepRecord record("room");
  record.add(50.0, metrics_with_entropy(6.0));
  record.add(0.0, metrics_with_entropy(2.0));
  record.add(50.0005, metrics_with_entropy(6.2));  // the same power as typed twice
  record.add(20.0, metrics_with_entropy(4.0));
  ASSERT_EQ(record.points().size(), 3u);
  EXPECT_DOUBLE_EQ(record.points()[0].power_w, 0.0);
  EXPECT_DOUBLE_EQ(record.points()[1].power_w, 20.0);
  EXPECT_EQ(record.points()[2].frames, 2);
  EXPECT_NEAR(record.points()[2].entropy_bits.mean, 6.1, 1e-12);
  EXPECT_THROW(record.add(-1.0, metrics_with_entropy(1.0)), std::invalid_argument);
  EXPECT_THROW(record.add(NAN, metrics_with_entropy(1.0)), std::invalid_argument);
  const auto samples = record.entropy_samples();
  ASSERT_EQ(samples.size(), 3u);
  EXPECT_DOUBLE_EQ(samples[2].weight, 2.0);

  // Merging a point equals adding its frames one by one.
  SweepRecord merged("room");
  SweepPoint half;
  half.power_w = 50.0;
  half.add(metrics_with_entropy(6.0));
  merged.add_point(half);
  SweepPoint other;
  other.power_w = 50.0;
  other.add(metrics_with_entropy(6.2));
  other.add(metrics_with_entropy(6.7));
  merged.add_point(other);
  SweepRecord direct("room");
  for (double v : {6.0, 6.2, 6.7}) direct.add(50.0, metrics_with_entropy(v));
  EXPECT_EQ(merged.points()[0].frames, 3);
  EXPECT_NEAR(merged.points()[0].entropy_bits.mean, direct.points()[0].entropy_bits.mean, 1e-15);
  EXPECT_NEAR(merged.points()[0].entropy_bits.stddev(), direct.points()[0].entropy_bits.stddev(), 1e-14);
}

IlluminationConfig test_config() {
  IlluminationConfig config = default_illumination_config();
  config.sweep.powers_w = {0, 20, 40, 70, 100};
  config.sweep.frames_per_power = 3;
  config.sweep.settle_frames = 2;
  config.scenes[0].prior = PowerPrior{50, 100, PriorBasis::Paper, "test"};
  return config;
}

const SaturationCurve kCurve{2.0, 7.5, 20.0};

// Feeds `frames` frames reporting `power` (as a source with its own lamp does).
void feed(SweepRecorder& recorder, double power, int frames, bool from_frame = true) {
  for (int i = 0; i < frames; ++i) recorder.add_frame(metrics_with_entropy(kCurve(power)), power, from_frame);
}

TEST(SweepRecorder, WalksThroughThePlanAndReplacesThePriorWithTheSweep) {
  SweepRecorder recorder(test_config());
  auto status = recorder.status();
  EXPECT_EQ(status->progress.stage, SweepStage::Idle);
  EXPECT_EQ(status->recommendation.source, RecommendationSource::Prior);
  EXPECT_DOUBLE_EQ(status->recommendation.power_w, 75.0);

  ASSERT_TRUE(recorder.apply(sweep_command::Start{}));
  status = recorder.status();
  EXPECT_EQ(status->progress.stage, SweepStage::AwaitingPower);
  EXPECT_EQ(status->requested_power_w(), 0.0);
  feed(recorder, 0.0, 5);  // frames before Capture are not recorded
  EXPECT_TRUE(recorder.status()->points.empty());

  for (const double power : {0.0, 20.0, 40.0, 70.0}) {
    SCOPED_TRACE(power);
    ASSERT_EQ(recorder.status()->requested_power_w(), power);
    ASSERT_TRUE(recorder.apply(sweep_command::Capture{power}));
    EXPECT_EQ(recorder.status()->progress.stage, SweepStage::Capturing);
    feed(recorder, power, 2);
    EXPECT_EQ(recorder.status()->progress.frames_captured, 2);
    feed(recorder, power, 1);
  }
  status = recorder.status();
  EXPECT_EQ(status->points.size(), 4u);
  EXPECT_EQ(status->points[2].frames, 3);
  EXPECT_EQ(status->recommendation.source, RecommendationSource::Sweep) << "four powers replace the prior";
  EXPECT_EQ(status->requested_power_w(), 100.0);

  ASSERT_TRUE(recorder.apply(sweep_command::Skip{}));
  status = recorder.status();
  EXPECT_EQ(status->progress.stage, SweepStage::Complete);
  EXPECT_FALSE(recorder.apply(sweep_command::Skip{})) << "nothing left to skip";
  EXPECT_NEAR(status->recommendation.power_w, 20.0 * std::log(5.5 / 0.15), 0.5);
}

TEST(SweepRecorder, SettlesAfterAManualPowerChangeAndIgnoresFramesOfAnotherPower) {
  SweepRecorder recorder(test_config());
  ASSERT_TRUE(recorder.apply(sweep_command::Start{}));
  ASSERT_TRUE(recorder.apply(sweep_command::Capture{0.0}));
  // Frames whose power is the operator's setting (manual lamp): two settle frames are skipped.
  feed(recorder, 0.0, 2, /*from_frame=*/false);
  EXPECT_EQ(recorder.status()->progress.frames_captured, 0);
  EXPECT_EQ(recorder.status()->progress.settle_remaining, 0);
  feed(recorder, 0.0, 1, false);
  EXPECT_EQ(recorder.status()->progress.frames_captured, 1);
  // A frame still at another power (in the camera's pipeline) is not counted.
  feed(recorder, 20.0, 1);
  EXPECT_EQ(recorder.status()->progress.frames_captured, 1);
  EXPECT_EQ(recorder.status()->progress.frames_ignored, 1);
  feed(recorder, 0.0, 2, false);
  EXPECT_EQ(recorder.status()->progress.stage, SweepStage::AwaitingPower);
  ASSERT_EQ(recorder.status()->points.size(), 1u);
  EXPECT_EQ(recorder.status()->points[0].frames, 3);
}

TEST(SweepRecorder, KeepsOneSweepPerSceneAndRefusesBadCommands) {
  SweepRecorder recorder(test_config());
  ASSERT_TRUE(recorder.apply(sweep_command::Start{}));
  ASSERT_TRUE(recorder.apply(sweep_command::Capture{0.0}));
  feed(recorder, 0.0, 3);
  ASSERT_TRUE(recorder.apply(sweep_command::SelectScene{"tunnel"}));
  auto status = recorder.status();
  const SceneType* scene = status->scene();
  ASSERT_NE(scene, nullptr);
  EXPECT_EQ(scene->name, "tunnel");
  EXPECT_TRUE(status->points.empty());
  EXPECT_EQ(status->progress.stage, SweepStage::Idle) << "switching scenes ends the wizard";
  EXPECT_EQ(status->recommendation.source, RecommendationSource::None) << "the test config has no tunnel prior";
  ASSERT_TRUE(recorder.apply(sweep_command::SelectScene{"indoor"}));
  EXPECT_EQ(recorder.status()->points.size(), 1u) << "the room's sweep is kept";
  EXPECT_EQ(recorder.sweep("room").points().size(), 1u);

  const auto revision = recorder.status()->revision;
  EXPECT_FALSE(recorder.apply(sweep_command::SelectScene{"moon"}));
  EXPECT_EQ(recorder.status()->message, "unknown scene 'moon'");
  EXPECT_GT(recorder.status()->revision, revision);
  EXPECT_FALSE(recorder.apply(sweep_command::Capture{-5.0}));
  EXPECT_FALSE(recorder.apply(sweep_command::Start{{0, 500}, 0})) << "beyond the illuminator";
  EXPECT_FALSE(recorder.apply(sweep_command::SetSettings{{.plateau_share = 1.2}}));

  ASSERT_TRUE(recorder.apply(sweep_command::SetSettings{{.plateau_share = 0.9, .max_saturated_fraction = 0.02}}));
  EXPECT_DOUBLE_EQ(recorder.status()->settings.plateau_share, 0.9);
  EXPECT_DOUBLE_EQ(recorder.config().exposure.max_saturated_fraction, 0.02);
  ASSERT_TRUE(recorder.apply(sweep_command::Clear{}));
  EXPECT_TRUE(recorder.status()->points.empty());
}

TEST(SweepRecorder, CapturingAPowerAgainReplacesItsFrames) {
  SweepRecorder recorder(test_config());
  ASSERT_TRUE(recorder.apply(sweep_command::Capture{40.0}));  // outside the wizard
  feed(recorder, 40.0, 3);
  EXPECT_EQ(recorder.status()->progress.stage, SweepStage::Complete);
  ASSERT_TRUE(recorder.apply(sweep_command::Capture{40.0}));
  feed(recorder, 40.0, 1);
  ASSERT_EQ(recorder.status()->points.size(), 1u);
  EXPECT_EQ(recorder.status()->points[0].frames, 1);
  ASSERT_TRUE(recorder.apply(sweep_command::Finish{}));
  EXPECT_EQ(recorder.status()->progress.stage, SweepStage::Complete);
  EXPECT_EQ(recorder.status()->points[0].frames, 1) << "frames captured before Finish are kept";
}

}  // namespace
}  // namespace nirslam
