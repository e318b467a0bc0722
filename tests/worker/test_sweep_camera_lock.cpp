// The power sweep's camera lock: a live emulated camera under auto exposure is held at one
// exposure while the wizard sweeps (its frames show it) and runs its auto exposure again after;
// the operator's own lock is kept, an operator who unlocks mid-sweep is not overruled, a camera
// replaced mid-sweep gets its lock back, and a device that refuses auto exposure says so. The
// live test runs under ThreadSanitizer with the worker tests (GUI thread, capture thread).

#include <chrono>
#include <memory>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "core/test_v4l2_fixtures.hpp"
#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/illumination/sweep_camera_lock.hpp"
#include "text_contains.hpp"

namespace nirslam {
namespace {

using namespace std::chrono_literals;
using Event = SweepCameraLock::Event;

template <typename Done>
bool wait_for_state(const CameraControls& controls, Done done) {
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!done(controls.state())) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

// The exposures (100 us units) of the next `count` frames the source delivers.
std::vector<std::int32_t> next_exposures(V4l2Source& source, EmulatedUvc& emulator, int count) {
  emulator.allow_frames("/dev/video0", count);
  std::vector<std::int32_t> exposures;
  for (int i = 0; i < count; ++i) {
    const auto frame = source.next();
    if (!frame) break;
    exposures.push_back(static_cast<std::int32_t>(std::lround(*frame->exposure_ms * 10.0)));
  }
  return exposures;
}

TEST(SweepCameraLock, HoldsALiveCamerasAutoExposureForTheSweepAndGivesItBack) {
  EmulatedCameraSpec camera = testing::small_camera();
  camera.exposure_default = 10;  // 1 ms; the auto exposure heads for 100 units (10 ms) at gain 16
  auto emulator = testing::emulator_with(camera);
  emulator->limit_frames("/dev/video0", 0);  // the test decides when frames come
  V4l2SourceSpec spec;
  spec.format = PixelFormat::Grey;
  spec.width = 64;
  spec.height = 48;
  spec.queue_capacity = 64;
  spec.auto_exposure = true;
  const auto source = open_v4l2_source(spec, emulator);
  const std::shared_ptr<CameraControls> controls = source->controls();
  ASSERT_TRUE(wait_for_state(*controls, [](const CameraState& s) { return s.auto_exposure; }));

  SweepCameraLock lock;
  EXPECT_EQ(lock.update(SweepStage::Idle, controls).event, Event::None);
  EXPECT_FALSE(lock.holding());

  const SweepCameraLock::Change locked = lock.update(SweepStage::AwaitingPower, controls);
  EXPECT_EQ(locked.event, Event::Locked);
  EXPECT_TRUE(contains(locked.message, "/dev/video0")) << locked.message;
  EXPECT_TRUE(contains(locked.message, "auto exposure off")) << locked.message;
  ASSERT_TRUE(wait_for_state(*controls, [](const CameraState& s) { return s.locked && !s.auto_exposure; }));
  EXPECT_THROW(controls->set_exposure_ms(20.0), InputError);  // the operator's slider is held too

  const std::vector<std::int32_t> during = next_exposures(*source, *emulator, 4);
  ASSERT_EQ(during.size(), 4u);
  EXPECT_EQ(std::set<std::int32_t>(during.begin(), during.end()).size(), 1u) << "the exposure moved during the sweep";
  EXPECT_EQ(lock.update(SweepStage::Capturing, controls).event, Event::None);
  ASSERT_TRUE(lock.holding());
  EXPECT_EQ(*lock.holding(), "held at 1 ms, gain 1x until the sweep ends");

  const SweepCameraLock::Change released = lock.update(SweepStage::Complete, controls);
  EXPECT_EQ(released.event, Event::Released) << released.message;
  EXPECT_TRUE(contains(released.message, "auto exposure back on")) << released.message;
  EXPECT_FALSE(lock.holding());
  ASSERT_TRUE(wait_for_state(*controls, [](const CameraState& s) { return !s.locked && s.auto_exposure; }));
  const std::vector<std::int32_t> after = next_exposures(*source, *emulator, 3);
  ASSERT_EQ(after.size(), 3u);
  EXPECT_GT(after.front(), during.back());  // heading for 10 ms again, half-way a frame
  EXPECT_GT(after.back(), after.front());
  EXPECT_EQ(lock.update(SweepStage::Complete, controls).event, Event::None);
}

// A camera whose state follows the calls at once, recording them.
class ImmediateCamera final : public CameraControls {
public:
  explicit ImmediateCamera(bool auto_exposure, bool refuse_auto_exposure = false) : refuse_(refuse_auto_exposure) {
    state_.device = "/dev/video4";
    state_.connection = CameraConnection::Streaming;
    state_.auto_exposure_available = true;
    state_.auto_exposure = auto_exposure;
    state_.exposure_ms = {true, 0.1, 30.0, 0.1, 10.0};
    state_.gain = {true, 16.0, 128.0, 1.0, 16.0};
    state_.gain_unity = 16.0;
    state_.exposure_in_effect_ms = 4.0;
    state_.gain_in_effect = 16.0;
  }
  CameraState state() const override { return state_; }
  void set_exposure_ms(double exposure_ms) override {
    state_.exposure_in_effect_ms = exposure_ms;
    state_.auto_exposure = false;
  }
  void set_gain(double gain) override { state_.gain_in_effect = gain; }
  void set_auto_exposure(bool on) override {
    if (refuse_) throw InputError(state_.device, "auto_exposure", "refused by the test device");
    state_.auto_exposure = on;
  }
  void set_frame_rate(double) override {}
  void set_locked(bool locked) override {
    state_.locked = locked;
    if (locked) state_.auto_exposure = false;
  }

private:
  CameraState state_;
  bool refuse_;
};

TEST(SweepCameraLock, KeepsTheOperatorsLockAndDoesNotOverruleAnUnlock) {
  auto camera = std::make_shared<ImmediateCamera>(false);
  camera->set_locked(true);
  SweepCameraLock lock;
  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, camera).event, Event::OperatorsLock);
  EXPECT_FALSE(lock.holding());
  EXPECT_EQ(lock.update(SweepStage::Complete, camera).event, Event::None);
  EXPECT_TRUE(camera->state().locked);  // the operator's lock outlives the sweep

  camera->set_locked(false);
  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, camera).event, Event::Locked);
  EXPECT_EQ(lock.update(SweepStage::Capturing, camera).event, Event::None);
  camera->set_locked(false);  // the operator unlocks in the Camera tab
  const SweepCameraLock::Change unlocked = lock.update(SweepStage::Capturing, camera);
  EXPECT_EQ(unlocked.event, Event::OperatorUnlocked);
  EXPECT_TRUE(contains(unlocked.message, "follows the lamp")) << unlocked.message;
  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, camera).event, Event::None);
  EXPECT_FALSE(camera->state().locked);
  EXPECT_EQ(lock.update(SweepStage::Idle, camera).event, Event::None);
  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, camera).event, Event::Locked);  // the next sweep locks again
}

TEST(SweepCameraLock, AReplacedCameraGetsItsAutoExposureBackAndTheNewOneIsHeld) {
  auto first = std::make_shared<ImmediateCamera>(true);
  auto second = std::make_shared<ImmediateCamera>(true);
  SweepCameraLock lock;
  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, first).event, Event::Locked);
  EXPECT_FALSE(first->state().auto_exposure);
  EXPECT_EQ(lock.update(SweepStage::Capturing, second).event, Event::Released);
  EXPECT_TRUE(first->state().auto_exposure);
  EXPECT_FALSE(first->state().locked);
  EXPECT_EQ(lock.update(SweepStage::Capturing, second).event, Event::Locked);
  EXPECT_TRUE(second->state().locked);
  EXPECT_EQ(lock.update(SweepStage::Capturing, nullptr).event, Event::Released);  // the camera closed
  EXPECT_TRUE(second->state().auto_exposure);
  EXPECT_EQ(lock.update(SweepStage::Capturing, nullptr).event, Event::None);
}

TEST(SweepCameraLock, ADeviceThatRefusesAutoExposureAfterTheSweepSaysSo) {
  auto camera = std::make_shared<ImmediateCamera>(true, true);
  SweepCameraLock lock;
  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, camera).event, Event::Locked);
  const SweepCameraLock::Change change = lock.update(SweepStage::Complete, camera);
  EXPECT_EQ(change.event, Event::Failed);
  EXPECT_TRUE(contains(change.message, "could not be turned back on")) << change.message;
  EXPECT_TRUE(contains(change.message, "refused by the test device")) << change.message;
  EXPECT_FALSE(camera->state().locked);
}

TEST(SweepCameraLock, TheNextSweepTakesTheAdvisedExposureThenGainWhereTheExposureEnds) {
  auto camera = std::make_shared<ImmediateCamera>(true);
  SweepCameraLock lock;
  EXPECT_FALSE(lock.last_sweep_exposure_ms());
  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, camera).event, Event::Locked);
  EXPECT_EQ(lock.update(SweepStage::Capturing, camera).event, Event::None);
  EXPECT_EQ(lock.last_sweep_exposure_ms(), 4.0);
  EXPECT_EQ(lock.update(SweepStage::Complete, camera).event, Event::Released);
  EXPECT_TRUE(camera->state().auto_exposure);

  lock.sweep_again_at(5.0);  // 20 ms: within the exposure's range
  const SweepCameraLock::Change longer = lock.update(SweepStage::AwaitingPower, camera);
  EXPECT_EQ(longer.event, Event::Locked);
  EXPECT_TRUE(contains(longer.message, "at 20 ms, 5.0x the last sweep's")) << longer.message;
  EXPECT_EQ(camera->state().exposure_in_effect_ms, 20.0);
  EXPECT_TRUE(camera->state().locked);
  EXPECT_EQ(lock.update(SweepStage::Capturing, camera).event, Event::None);
  EXPECT_EQ(lock.update(SweepStage::Complete, camera).event, Event::Released);
  EXPECT_TRUE(camera->state().auto_exposure) << "auto exposure comes back after the second sweep too";

  lock.sweep_again_at(3.0);  // 60 ms: the exposure stops at 30, the gain doubles
  const SweepCameraLock::Change gained = lock.update(SweepStage::AwaitingPower, camera);
  EXPECT_TRUE(contains(gained.message, "at 30 ms, gain 2x, 3.0x the last sweep's")) << gained.message;
  EXPECT_EQ(camera->state().gain_in_effect, 32.0);
  EXPECT_EQ(lock.update(SweepStage::Capturing, camera).event, Event::None);
  EXPECT_EQ(lock.update(SweepStage::Complete, camera).event, Event::Released);

  lock.sweep_again_at(20.0);  // beyond the gain's range too: said so
  const SweepCameraLock::Change limited = lock.update(SweepStage::AwaitingPower, camera);
  EXPECT_TRUE(contains(limited.message, "the camera's limit; 20.0x was advised")) << limited.message;
  EXPECT_EQ(lock.update(SweepStage::Complete, camera).event, Event::Released);

  EXPECT_EQ(lock.update(SweepStage::AwaitingPower, camera).event, Event::Locked);  // the factor was used once
  EXPECT_EQ(camera->state().exposure_in_effect_ms, 30.0);
}

}  // namespace
}  // namespace nirslam
