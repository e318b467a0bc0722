// The simulator's camera controls, as a V4L2 camera offers them: a lock holds the exposure its
// auto exposure had reached, a manual exposure ends auto exposure and shows in the frames, auto
// exposure comes back, the frame rate is refused by name, a rewind keeps what the operator set;
// and a frame limit hands on the lamp, the truth and the controls of the source it limits.

#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/frame_limit.hpp"
#include "text_contains.hpp"
#include "worker/still_rig_sweep.hpp"

namespace nirslam {
namespace {

// The sweep tests' still rig, smaller, under its auto exposure from a short start.
SimulatorOptions small_room_under_auto_exposure() {
  SimulatorOptions o = testing::still_rig();
  o.width = 64;
  o.height = 48;
  o.exposure_mode = ExposureMode::Auto;
  o.exposure_ms = 0.5;  // the auto exposure ramps up from here
  return o;
}

std::vector<double> exposures_of_next(Source& source, int frames) {
  std::vector<double> out;
  for (int i = 0; i < frames; ++i)
    if (const auto frame = source.next()) out.push_back(*frame->exposure_ms);
  return out;
}

TEST(SimulatedCamera, ControlsDriveTheSimulatorsExposureAsACamerasDo) {
  SimulatedSource source(small_room_under_auto_exposure());
  const std::shared_ptr<CameraControls> controls = source.camera_controls();
  ASSERT_NE(controls, nullptr);
  CameraState state = controls->state();
  EXPECT_EQ(state.device, "sim:room");
  EXPECT_EQ(state.format, "GREY 64x48");
  EXPECT_TRUE(state.auto_exposure);
  EXPECT_FALSE(state.locked);
  EXPECT_FALSE(state.gain.available) << "the default simulator has no gain to set";

  const std::vector<double> ramp = exposures_of_next(source, 4);
  ASSERT_EQ(ramp.size(), 4u);
  EXPECT_GT(ramp.back(), ramp.front()) << "auto exposure ramps up";

  controls->set_locked(true);
  EXPECT_THROW(controls->set_exposure_ms(8.0), InputError);
  const std::vector<double> held = exposures_of_next(source, 4);
  EXPECT_EQ(std::set<double>(held.begin(), held.end()).size(), 1u) << "the lock holds one exposure";
  EXPECT_GT(held.front(), ramp.back()) << "the one auto exposure had reached";
  state = controls->state();
  EXPECT_TRUE(state.locked);
  EXPECT_FALSE(state.auto_exposure);
  EXPECT_EQ(state.exposure_in_effect_ms, held.back());
  EXPECT_EQ(state.frames_captured, 8);

  controls->set_locked(false);
  controls->set_exposure_ms(8.0);  // allowed at once: the unlock is already asked for
  EXPECT_EQ(exposures_of_next(source, 2), (std::vector<double>{8.0, 8.0}));
  EXPECT_FALSE(controls->state().auto_exposure);
  try {
    controls->set_exposure_ms(500.0);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "exposure_ms");
    EXPECT_TRUE(contains(e.what(), "outside the device's range")) << e.what();
  }
  try {
    controls->set_frame_rate(60.0);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "fps");
    EXPECT_TRUE(contains(e.what(), "frame rate is its sequence's")) << e.what();
  }

  source.rewind();  // a rewind keeps the operator's exposure
  EXPECT_EQ(exposures_of_next(source, 2), (std::vector<double>{8.0, 8.0}));

  controls->set_auto_exposure(true);
  const std::vector<double> resumed = exposures_of_next(source, 6);
  EXPECT_NE(resumed.back(), 8.0) << "auto exposure moves again";
  EXPECT_TRUE(controls->state().auto_exposure);
}

TEST(SimulatedCamera, AFrameLimitHandsOnTheLampTheTruthAndTheControls) {
  SimulatorOptions o = small_room_under_auto_exposure();
  o.powers_w = {20.0};
  auto inner = std::make_unique<SimulatedSource>(o);
  const auto lamp = inner->illuminator();
  const auto controls = inner->camera_controls();
  const std::unique_ptr<Source> limited = limit_frames(std::move(inner), 3);
  EXPECT_EQ(limited->illuminator(), lamp);
  EXPECT_EQ(limited->camera_controls(), controls);
  ASSERT_TRUE(limited->photometric_truth().has_value());
  EXPECT_TRUE(limited->photometric_truth()->halo.has_value());
  EXPECT_EQ(exposures_of_next(*limited, 5).size(), 3u);
}

}  // namespace
}  // namespace nirslam
