// OnlinePhotometricCalibration (issue 6): the front end on the caller's thread, the back end on
// its own; estimate() read from a third thread. In the worker suite so CI runs it under
// ThreadSanitizer.
#include <atomic>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>
#include <thread>

#include <gtest/gtest.h>

#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/sim/simulator.hpp"
#include "core/simulator_fixtures.hpp"
#include "opencv_serial_under_tsan.hpp"

namespace nirslam {
namespace {

TEST(PhotometricOnlineCalibration, BackgroundBackEndPublishesWhileAReaderPolls) {
  OnlineCalibrationOptions options;
  options.queue_capacity = 2;
  OnlinePhotometricCalibration calibration(options);
  std::atomic<bool> done{false};
  std::atomic<int> versions_seen{0};
  std::thread reader([&] {
    int last = 0;
    while (!done.load()) {
      const auto e = calibration.estimate();
      ASSERT_NE(e, nullptr);
      EXPECT_TRUE(e->response.coefficients().allFinite());
      if (e->model_version != last) ++versions_seen, last = e->model_version;
      std::this_thread::yield();
    }
  });
  Simulator sim(test_sequences::small_ambient_room(60));
  int keyframes = 0;
  while (auto f = sim.next()) {
    const CorrectedFrame out = calibration.process(f->frame);
    keyframes += out.keyframe;
    ASSERT_EQ(out.irradiance.type(), CV_32FC1);
    EXPECT_TRUE(std::isfinite(out.front_end_ms));
  }
  calibration.finish();
  done = true;
  reader.join();
  const auto e = calibration.estimate();
  EXPECT_GT(keyframes, 5);
  EXPECT_GT(e->model_version, 0) << e->status;
  EXPECT_EQ(e->ambiguity, AmbiguityResolution::KnownExposures);
  EXPECT_FALSE(e->status.empty());
  EXPECT_EQ(calibration.exposure_history().size(), 60u);
  EXPECT_GE(calibration.keyframes_dropped(), 0);
  calibration.reset();
  EXPECT_EQ(calibration.estimate()->model_version, 0);
  EXPECT_TRUE(calibration.exposure_history().empty());
}

// The corrected frames follow a new estimate in bounded steps (the odometry compares frames
// corrected over a second or more), and reach it.
TEST(PhotometricOnlineCalibration, CorrectionFollowsTheEstimateInBoundedSteps) {
  OnlineCalibrationOptions options;
  options.background_thread = false;
  options.max_correction_step_log = 0.05;
  OnlinePhotometricCalibration calibration(options);
  Simulator sim(test_sequences::small_ambient_room(80));
  std::vector<Frame> frames;
  while (auto f = sim.next()) frames.push_back(f->frame);
  // Over the grey range the fit saw (outside it G is extrapolated and the frames seldom go).
  auto largest_step = [&](const ResponseModel& a, const ResponseModel& b, const VignetteModel& va, const VignetteModel& vb) {
    const auto e = calibration.estimate();
    const double low = e->grey_high > e->grey_low ? std::max(e->grey_low, 2.0) : 8.0;
    const double high = e->grey_high > e->grey_low ? std::min(e->grey_high, 253.0) : 247.0;
    double largest = 0.0;
    for (double g = low; g <= high; g += (high - low) / 16.0)
      largest = std::max(largest, std::abs(std::log(a.inverse(g / 255.0) / b.inverse(g / 255.0))));
    for (double r = 0.0; r <= 1.0; r += 0.125) largest = std::max(largest, std::abs(std::log(va(r) / vb(r))));
    return largest;
  };
  // The first frame is corrected with the estimate as it is (the initial model).
  calibration.process(frames.front());
  EXPECT_EQ(calibration.correction_response().coefficients(), calibration.estimate()->response.coefficients());
  ResponseModel previous = calibration.correction_response();
  VignetteModel previous_vignette = calibration.correction_vignette();
  double worst = 0.0;
  int moved = 0;
  auto run = [&](const Frame& frame) {
    calibration.process(frame);
    const double step = largest_step(calibration.correction_response(), previous, calibration.correction_vignette(),
                                     previous_vignette);
    worst = std::max(worst, step);
    moved += step > 0.0;
    previous = calibration.correction_response();
    previous_vignette = calibration.correction_vignette();
  };
  for (std::size_t i = 1; i < frames.size(); ++i) run(frames[i]);
  calibration.finish();
  const auto e = calibration.estimate();
  ASSERT_GT(e->model_version, 0) << e->status;
  std::printf("largest correction step %.4f (limit %.2f), %d frames moved it\n", worst, options.max_correction_step_log, moved);
  // A step along the coefficients is not exactly proportional in log G: some slack.
  EXPECT_LT(worst, 2.0 * options.max_correction_step_log);
  EXPECT_GT(moved, 3) << "the estimate moved away from the start: several steps";
  for (int i = 0; i < 400 && largest_step(calibration.correction_response(), e->response, calibration.correction_vignette(),
                                            e->vignette) > 0.0; ++i)
    run(frames[static_cast<std::size_t>(i) % frames.size()]);
  EXPECT_EQ(calibration.correction_response().coefficients(), calibration.estimate()->response.coefficients());
  EXPECT_EQ(calibration.correction_vignette().v, calibration.estimate()->vignette.v);
}

// Distances learnt late (the pipeline's lamp_distance_backfill): queued from the caller's thread
// while the back end works on its own, and filled into the keyframes they belong to.
TEST(PhotometricOnlineCalibration, IlluminationFilledInLaterReachesTheStoredKeyframes) {
  OnlineCalibrationOptions options;
  OnlinePhotometricCalibration calibration(options);
  // Odd tracks have their distance at once, even ones only three frames later.
  FrameIllumination illumination;
  illumination.track_light_distance_m = [](std::int64_t id, const Eigen::Vector2d&) -> std::optional<double> {
    if (id % 2 == 0) return std::nullopt;
    return 2.0;
  };
  illumination.power_w = 1.0;  // the room is lit by ambient light alone: the simulator reports 0 W
  const double late_log_illumination = log_illumination(1.0, 2.0);
  std::vector<std::pair<std::int64_t, std::vector<std::int64_t>>> waiting;  // keyframe -> even tracks
  Simulator sim(test_sequences::small_ambient_room(40));
  int keyframes = 0;
  while (auto f = sim.next()) {
    const CorrectedFrame out = calibration.process(f->frame, illumination);
    if (out.keyframe) {
      ++keyframes;
      std::vector<std::int64_t> even;
      for (const TrackObservation& t : calibration.last_tracks())
        if (t.id % 2 == 0) even.push_back(t.id);
      waiting.emplace_back(f->frame.index, std::move(even));
    }
    while (!waiting.empty() && waiting.front().first + 3 <= f->frame.index) {
      std::vector<TrackIllumination> values;
      for (const std::int64_t id : waiting.front().second) values.push_back({id, late_log_illumination});
      calibration.fill_unknown_illumination(waiting.front().first, std::move(values));
      waiting.erase(waiting.begin());
    }
  }
  calibration.finish();
  const std::vector<PhotometricKeyframe> stored = calibration.stored_keyframes();
  ASSERT_GT(keyframes, 5);
  ASSERT_FALSE(stored.empty());
  std::int64_t even_observations = 0, unknown = 0;
  for (const PhotometricKeyframe& k : stored) {
    EXPECT_TRUE(k.illumination_modelled);
    const bool answered = k.frame_index + 3 <= 39;
    for (const KeyframeObservation& o : k.observations) {
      even_observations += o.track_id % 2 == 0 && answered;
      unknown += !std::isfinite(o.log_illumination);
      if (o.track_id % 2 == 0 && answered) {
        EXPECT_FLOAT_EQ(o.log_illumination, static_cast<float>(late_log_illumination));
      }
    }
    if (!answered) {
      EXPECT_TRUE(std::any_of(k.observations.begin(), k.observations.end(), [](const KeyframeObservation& o) {
        return !std::isfinite(o.log_illumination);
      })) << "the last keyframes' even tracks were never answered";
    }
  }
  EXPECT_GT(even_observations, 50);
  EXPECT_EQ(calibration.illumination_filled(), even_observations);
  std::printf("%d keyframes, %zu stored, %lld observations filled in later, %lld left unknown\n", keyframes, stored.size(),
              static_cast<long long>(calibration.illumination_filled()), static_cast<long long>(unknown));
  calibration.reset();
  EXPECT_EQ(calibration.illumination_filled(), 0);
  EXPECT_TRUE(calibration.stored_keyframes().empty());
}

TEST(PhotometricOnlineCalibration, DegenerateFramesKeepTheLastEstimateNeverNaN) {
  OnlineCalibrationOptions options;
  options.background_thread = false;
  OnlinePhotometricCalibration calibration(options);
  const cv::Mat black = cv::Mat::zeros(180, 240, CV_8UC1);
  const cv::Mat white(180, 240, CV_8UC1, cv::Scalar(255));
  const cv::Mat flat(180, 240, CV_8UC1, cv::Scalar(90));
  std::int64_t index = 0;
  for (const cv::Mat* image : {&black, &white, &flat, &black}) {
    Frame frame;
    frame.image = *image;
    frame.index = index++;
    frame.timestamp_s = 0.1 * static_cast<double>(frame.index);
    const CorrectedFrame out = calibration.process(frame);
    EXPECT_FALSE(out.keyframe);
    EXPECT_FALSE(out.estimate.reason.empty());
    EXPECT_FALSE(out.exposure.has_value() && !std::isfinite(*out.exposure));
    cv::Mat mask = out.irradiance != out.irradiance;  // NaN test
    EXPECT_EQ(cv::countNonZero(mask), 0);
  }
  // A static camera at a constant exposure: keyframes only by time, nothing observable.
  Simulator sim(test_sequences::small_ambient_room(1));
  const Frame still = sim.next()->frame;
  for (int i = 0; i < 40; ++i) {
    Frame frame = still;
    frame.index = index++;
    frame.timestamp_s = 0.5 * static_cast<double>(i);
    calibration.process(frame);
  }
  calibration.finish();
  const auto e = calibration.estimate();
  EXPECT_EQ(e->model_version, 0) << e->status;
  EXPECT_NE(e->status.find("nothing observable"), std::string::npos) << e->status;
  EXPECT_TRUE(e->response.coefficients().allFinite());
  EXPECT_TRUE(e->vignette.v.allFinite());
}

}  // namespace
}  // namespace nirslam
