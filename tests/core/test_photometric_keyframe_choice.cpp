// Which frames become the photometric back end's keyframes when the source reports exposures
// (OnlineCalibrationOptions::keyframes_by_reported_exposure): the reported exposure's change
// decides, not the front end's estimate, which under a co-located lamp moves with the lamp's
// distance.
#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/sim/simulator.hpp"
#include "simulator_fixtures.hpp"

namespace nirslam {
namespace {

// The frames that became keyframes; with `stepped` the reported exposure (not the image) is
// 10 % higher every 6 frames, so only a choice that reads the reported value sees a change.
std::vector<std::int64_t> keyframes(bool by_reported, bool stepped) {
  OnlineCalibrationOptions options;
  options.background_thread = false;
  options.keyframes_by_reported_exposure = by_reported;
  // Keyframes on exposure changes only (not on motion or track turnover).
  options.keyframes.min_mean_motion_px = 1e9;
  options.keyframes.min_track_turnover = 2.0;
  OnlinePhotometricCalibration calibration(options);
  Simulator sim(test_sequences::small_ambient_room(48));
  std::vector<std::int64_t> chosen;
  while (auto f = sim.next()) {
    Frame frame = f->frame;
    if (stepped) *frame.exposure_ms *= std::pow(1.1, static_cast<double>(frame.index / 6));
    if (calibration.process(frame).keyframe) chosen.push_back(frame.index);
  }
  return chosen;
}

// The step frames 12, 18, .. 42 (after the auto exposure's ramp, which makes keyframes 0-10 in
// every variant) that became keyframes.
int steps_chosen(const std::vector<std::int64_t>& chosen) {
  int n = 0;
  for (std::int64_t i = 12; i < 48; i += 6) n += static_cast<int>(std::count(chosen.begin(), chosen.end(), i));
  return n;
}

TEST(PhotometricKeyframeChoice, AReportedExposureChangeMakesAKeyframe) {
  const std::vector<std::int64_t> plain = keyframes(true, false);
  const std::vector<std::int64_t> stepped = keyframes(true, true);
  ASSERT_FALSE(plain.empty());
  EXPECT_EQ(steps_chosen(plain), 0);
  EXPECT_EQ(steps_chosen(stepped), 6) << "all 6 steps";
  EXPECT_GT(stepped.size(), plain.size());
}

TEST(PhotometricKeyframeChoice, WithoutItTheEstimateDecides) {
  // The estimate follows the images, which do not step: the step frames are not chosen (the
  // keyframes still differ a little, since the back end holds the reported exposures and its
  // model, hence the estimate, changes with them).
  const std::vector<std::int64_t> stepped = keyframes(false, true);
  ASSERT_FALSE(stepped.empty());
  EXPECT_LE(steps_chosen(stepped), 1);
}

}  // namespace
}  // namespace nirslam
