// OnlinePhotometricCalibration (issue 6): the front end on the caller's thread, the back end on
// its own; estimate() read from a third thread. In the worker suite so CI runs it under
// ThreadSanitizer.
#include <atomic>
#include <cmath>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/core/utility.hpp>

#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam {
namespace {

#if defined(__SANITIZE_THREAD__)
// OpenCV's parallel_for_ runs on TBB, which ThreadSanitizer cannot see: run its loops serially.
const bool opencv_loops_serial = [] {
  cv::setNumThreads(0);
  return true;
}();
#endif

SimulatorOptions small_room(std::int64_t frames) {
  SimulatorOptions o;
  o.scene = sim::SceneKind::Room;
  o.width = 240;
  o.height = 180;
  o.supersampling = 1;
  o.frames = frames;
  o.exposure_ms = 2.0;
  o.powers_w = {0.0};
  o.ambient_irradiance = 0.4;
  return o;
}

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
  Simulator sim(small_room(60));
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
  Simulator sim(small_room(1));
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
