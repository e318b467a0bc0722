// The V4L2 source streaming from the emulated UVC driver: N frames with the driver's timestamps
// and the exposure and gain each was taken with, dropped frames counted from sequence gaps and
// from a lagging consumer, every format through the whole path, side-by-side stereo, an unplug in
// mid-stream (frames before it kept, stream ended with a message), reconnection, and the errors
// for a busy device, an unsupported format and controls out of range.

#include <linux/videodev2.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"
#include "test_v4l2_fixtures.hpp"
#include "text_contains.hpp"

namespace nirslam {
namespace {

using namespace std::chrono_literals;
using testing::emulator_with;
using testing::small_camera;


// Waits (up to 5 s) until the camera state satisfies `done`: the capture thread applies changes
// between frames, a moment after the call that asked for them.
template <typename Done>
bool wait_for_state(const V4l2Source& source, Done done) {
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!done(source.controls()->state())) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

V4l2SourceSpec spec_for(PixelFormat format, int width = 64, int height = 48) {
  V4l2SourceSpec spec;
  spec.device = "/dev/video0";
  spec.format = format;
  spec.width = width;
  spec.height = height;
  spec.queue_capacity = 64;  // the tests read every frame unless they test dropping
  spec.reconnect_wait_s = 0.2;
  return spec;
}

TEST(V4l2Streaming, NFramesWithKernelTimestampsAndExposures) {
  constexpr int kFrames = 12;
  auto emulator = emulator_with(small_camera());
  emulator->limit_frames("/dev/video0", kFrames);  // exactly N frames exist: none to drop
  V4l2SourceSpec spec = spec_for(PixelFormat::Y16);
  spec.fps = 15.0;
  spec.exposure_ms = 4.2;
  spec.gain = 32;
  const auto source = open_v4l2_source(spec, emulator);
  EXPECT_EQ(source->info().kind, "v4l2");
  EXPECT_TRUE(source->info().live);
  EXPECT_FALSE(source->info().frame_count.has_value());
  EXPECT_NEAR(source->info().nominal_fps, 15.0, 1e-6);
  EXPECT_TRUE(contains(source->info().description, "/dev/video0")) << source->info().description;

  for (int i = 0; i < kFrames; ++i) {
    const auto frame = source->next();
    ASSERT_TRUE(frame.has_value()) << i;
    EXPECT_EQ(frame->index, i);
    EXPECT_NEAR(frame->timestamp_s, 1000.0 + i / 15.0, 1e-6);  // the driver's timestamp, sequence i
    ASSERT_TRUE(frame->exposure_ms.has_value());
    EXPECT_NEAR(*frame->exposure_ms, 4.2, 1e-9);
    ASSERT_TRUE(frame->gain.has_value());
    EXPECT_NEAR(*frame->gain, 2.0, 1e-9);  // 32 over the control's default 16
    EXPECT_EQ(frame->bit_depth, 16);
    EXPECT_EQ(frame->image.type(), CV_16UC1);
    EXPECT_EQ(frame->image.at<std::uint16_t>(3, 10), i * 3 + 10);  // the pixels of sequence i
  }
  EXPECT_EQ(source->frames_dropped(), 0);
  const auto used = emulator->exposures_used("/dev/video0");
  ASSERT_GE(used.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(used.at(0).first, 42);  // 4.2 ms in 100 us units reached the device
  EXPECT_EQ(used.at(0).second, 32);
}

TEST(V4l2Streaming, ExposureChangedMidStreamIsReportedByTheFramesTakenWithIt) {
  auto emulator = emulator_with(small_camera());
  emulator->limit_frames("/dev/video0", 3);
  const auto source = open_v4l2_source(spec_for(PixelFormat::Grey), emulator);
  const auto controls = source->controls();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(source->next().has_value());
  controls->set_exposure_ms(25.0);
  controls->set_gain(20);
  bool seen = false;
  for (int i = 0; i < 40 && !seen; ++i) {
    emulator->allow_frames("/dev/video0", 1);  // one frame at a time, racing the change
    const auto frame = source->next();
    ASSERT_TRUE(frame.has_value());
    // Every frame reports what the device used for its sequence: never a mix of old and new.
    const std::uint32_t sequence = static_cast<std::uint32_t>(std::stoul(frame->name.substr(frame->name.find('#') + 1)));
    const auto used = emulator->exposures_used("/dev/video0").at(sequence);
    EXPECT_NEAR(*frame->exposure_ms, used.first * 0.1, 1e-9) << frame->name;
    seen = std::abs(*frame->exposure_ms - 25.0) < 1e-9 && std::abs(*frame->gain - 20.0 / 16.0) < 1e-9;
  }
  EXPECT_TRUE(seen);
  const CameraState state = controls->state();
  EXPECT_NEAR(*state.exposure_in_effect_ms, 25.0, 1e-9);
  EXPECT_NEAR(state.exposure_ms.minimum, 0.1, 1e-12);
  EXPECT_NEAR(state.exposure_ms.maximum, 500.0, 1e-9);
  EXPECT_FALSE(state.auto_exposure);
}

TEST(V4l2Streaming, AutoExposureFramesCarryTheExposureTheCameraChose) {
  auto emulator = emulator_with(small_camera());
  V4l2SourceSpec spec = spec_for(PixelFormat::Grey);
  spec.auto_exposure = true;
  spec.gain = 64;  // the emulated camera's auto exposure heads for 100 * 16 / 64 = 25 units
  emulator->limit_frames("/dev/video0", 10);
  const auto source = open_v4l2_source(spec, emulator);
  std::vector<double> exposures;
  for (int i = 0; i < 10; ++i) {
    const auto frame = source->next();
    ASSERT_TRUE(frame.has_value());
    const auto used = emulator->exposures_used("/dev/video0").at(static_cast<std::uint32_t>(i));
    EXPECT_NEAR(*frame->exposure_ms, used.first * 0.1, 1e-9) << i;
    exposures.push_back(*frame->exposure_ms);
  }
  EXPECT_GT(exposures.front(), exposures.back());  // 10 ms falling towards 2.5 ms
  EXPECT_NEAR(exposures.back(), 2.5, 0.2);  // half-way each frame: within 0.2 ms after 10 frames
  EXPECT_TRUE(source->controls()->state().auto_exposure);
}

TEST(V4l2Streaming, DroppedFramesCountedFromSequenceGaps) {
  auto emulator = emulator_with(small_camera());
  emulator->drop_sequences("/dev/video0", {3, 4, 9});
  emulator->limit_frames("/dev/video0", 8);
  const auto source = open_v4l2_source(spec_for(PixelFormat::Grey), emulator);
  std::vector<double> timestamps;
  for (int i = 0; i < 8; ++i) timestamps.push_back(source->next()->timestamp_s);
  EXPECT_EQ(source->frames_dropped(), 3);
  EXPECT_EQ(source->controls()->state().frames_dropped_by_driver, 3);
  EXPECT_NEAR(timestamps[3] - timestamps[2], 3.0 / 30.0, 1e-6);  // sequences 2 -> 5
}

TEST(V4l2Streaming, ALaggingConsumerMakesTheQueueDropItsOldestFrame) {
  auto emulator = emulator_with(small_camera());
  V4l2SourceSpec spec = spec_for(PixelFormat::Grey);
  spec.queue_capacity = 2;
  const auto source = open_v4l2_source(spec, emulator);
  // The unpaced emulator delivers as fast as the capture thread asks; nobody reads meanwhile.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (source->controls()->state().frames_captured < 10 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(2ms);
  const CameraState state = source->controls()->state();
  ASSERT_GE(state.frames_captured, 10);
  EXPECT_GE(state.frames_dropped_by_queue, 8);
  const auto first = source->next();
  const auto second = source->next();
  ASSERT_TRUE(first && second);
  EXPECT_GE(first->index, 8);  // the oldest were dropped: the newest are kept
  EXPECT_GT(second->index, first->index);
  EXPECT_GE(source->frames_dropped(), 8);
}

// Every format, through the driver's buffers, the capture thread and the queue.
TEST(V4l2Streaming, EveryFormatArrivesConverted) {
  for (const PixelFormat format : {PixelFormat::Grey, PixelFormat::Y10, PixelFormat::Y12, PixelFormat::Y16, PixelFormat::Yuyv}) {
    SCOPED_TRACE(std::string(to_string(format)));
    auto emulator = emulator_with(small_camera());
    emulator->limit_frames("/dev/video0", 2);
    const auto source = open_v4l2_source(spec_for(format, 32, 24), emulator);
    source->next();
    const auto frame = source->next();  // sequence 1
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->image.size(), cv::Size(32, 24));
    EXPECT_EQ(frame->bit_depth, bit_depth_of(format));
    const double value = frame->bit_depth == 8 ? frame->image.at<std::uint8_t>(7, 20) : frame->image.at<std::uint16_t>(7, 20);
    EXPECT_EQ(value, 1 * 3 + 20);
  }
  // MJPG from the emulated NIR camera's own pattern: decoded, 8 bits, textured.
  auto emulator = std::make_shared<EmulatedUvc>();
  emulator->add_camera(emulated_mono_nir_camera());
  emulator->limit_frames("/dev/video0", 1);
  V4l2SourceSpec spec = spec_for(PixelFormat::Mjpg, 320, 240);
  const auto source = open_v4l2_source(spec, emulator);
  const auto frame = source->next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->image.type(), CV_8UC1);
  cv::Scalar mean, stddev;
  cv::meanStdDev(frame->image, mean, stddev);
  EXPECT_GT(mean[0], 40.0);
  EXPECT_GT(stddev[0], 10.0);
}

TEST(V4l2Streaming, SideBySideStereoGivesTheLeftViewAndKeepsTheRight) {
  EmulatedCameraSpec camera = small_camera();
  camera.formats = {{PixelFormat::Y12, {{64, 24}}, {30.0}}};
  auto emulator = emulator_with(camera);
  emulator->limit_frames("/dev/video0", 1);
  V4l2SourceSpec spec = spec_for(PixelFormat::Y12, 64, 24);
  spec.stereo_side_by_side = true;
  const auto source = open_v4l2_source(spec, emulator);
  const auto frame = source->next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->image.size(), cv::Size(32, 24));
  EXPECT_EQ(frame->image.at<std::uint16_t>(0, 5), 5);
  const auto right = source->last_right_image();
  ASSERT_TRUE(right.has_value());
  EXPECT_EQ(right->size(), cv::Size(32, 24));
  EXPECT_EQ(right->at<std::uint16_t>(0, 5), 32 + 5);  // column 37 of the whole frame
  EXPECT_TRUE(source->controls()->state().stereo_side_by_side);
}

TEST(V4l2Streaming, UnplugEndsTheStreamKeepingTheFramesBeforeIt) {
  auto emulator = emulator_with(small_camera());
  emulator->unplug_after("/dev/video0", 5);
  const auto source = open_v4l2_source(spec_for(PixelFormat::Y10), emulator);
  std::vector<std::int64_t> delivered;
  while (const auto frame = source->next()) delivered.push_back(frame->index);
  EXPECT_EQ(delivered, (std::vector<std::int64_t>{0, 1, 2, 3, 4}));
  EXPECT_FALSE(source->next().has_value());  // ended stays ended
  const CameraState state = source->controls()->state();
  EXPECT_EQ(state.connection, CameraConnection::Unplugged);
  EXPECT_TRUE(contains(state.message, "/dev/video0 was unplugged after 5 frames")) << state.message;
  // Start again while it is still away: a clear error, not a crash.
  EXPECT_THROW(source->rewind(), InputError);
  // Back again: rewind reopens it.
  emulator->replug("/dev/video0");
  source->rewind();
  const auto frame = source->next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(source->controls()->state().connection, CameraConnection::Streaming);
}

TEST(V4l2Streaming, ReconnectsWhenTheDeviceComesBackInTime) {
  auto emulator = emulator_with(small_camera());
  emulator->unplug_after("/dev/video0", 3);
  emulator->limit_frames("/dev/video0", 3);
  V4l2SourceSpec spec = spec_for(PixelFormat::Grey);
  spec.reconnect_wait_s = 10.0;
  spec.exposure_ms = 7.5;
  const auto source = open_v4l2_source(spec, emulator);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(source->next().has_value());
  std::thread replug([&] {
    std::this_thread::sleep_for(100ms);
    emulator->replug("/dev/video0");
    emulator->allow_frames("/dev/video0", 2);
  });
  const auto frame = source->next();  // waits through the unplug
  replug.join();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->index, 3);
  EXPECT_NEAR(frame->timestamp_s, 1000.0, 1e-6);  // the reopened device counts from 0 again
  EXPECT_NEAR(*frame->exposure_ms, 7.5, 1e-9);    // the exposure in effect was restored
  const CameraState state = source->controls()->state();
  EXPECT_EQ(state.connection, CameraConnection::Streaming);
  EXPECT_TRUE(contains(state.message, "reconnected")) << state.message;
}

TEST(V4l2Streaming, AStalledCameraIsAnErrorNotAHang) {
  auto emulator = emulator_with(small_camera());
  emulator->limit_frames("/dev/video0", 1);  // one frame, then the device sends nothing
  V4l2SourceSpec spec = spec_for(PixelFormat::Grey);
  spec.stall_timeout_s = 0.2;
  const auto source = open_v4l2_source(spec, emulator);
  ASSERT_TRUE(source->next().has_value());
  try {
    source->next();
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/dev/video0");
    EXPECT_TRUE(contains(e.what(), "no frame for 0.2 s")) << e.what();
  }
  EXPECT_TRUE(contains(source->controls()->state().error, "stalled"));
}

TEST(V4l2Streaming, BusyDeviceAndUnsupportedFormatAreClearErrors) {
  auto emulator = emulator_with(small_camera());
  const auto first = open_v4l2_source(spec_for(PixelFormat::Grey), emulator);
  try {
    open_v4l2_source(spec_for(PixelFormat::Grey), emulator);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/dev/video0");
    EXPECT_TRUE(contains(e.what(), "busy")) << e.what();
  }
  auto other = emulator_with(small_camera());
  try {
    open_v4l2_source(spec_for(PixelFormat::Mjpg), other);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "format");
    EXPECT_TRUE(contains(e.what(), "/dev/video0")) << e.what();
  }
}

TEST(V4l2Streaming, ControlsOutOfRangeOrLockedAreRefusedNamingTheControl) {
  auto emulator = emulator_with(small_camera());
  V4l2SourceSpec bad = spec_for(PixelFormat::Grey);
  bad.exposure_ms = 900.0;  // the camera stops at 500 ms
  try {
    open_v4l2_source(bad, emulator);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/dev/video0");
    EXPECT_EQ(e.field(), "exposure_ms");
    EXPECT_TRUE(contains(e.what(), "900 ms is outside the device's range 0.1..500 ms")) << e.what();
  }
  emulator->limit_frames("/dev/video0", 0);  // the controls need no frames
  const auto source = open_v4l2_source(spec_for(PixelFormat::Grey), emulator);
  const auto controls = source->controls();
  EXPECT_THROW(controls->set_gain(300), InputError);
  EXPECT_THROW(controls->set_exposure_ms(0.01), InputError);
  EXPECT_THROW(controls->set_frame_rate(120.0), InputError);
  controls->set_locked(true);
  ASSERT_TRUE(wait_for_state(*source, [](const CameraState& s) { return s.locked; }));
  try {
    controls->set_exposure_ms(20.0);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "exposure_ms");
    EXPECT_TRUE(contains(e.what(), "locked")) << e.what();
  }
  EXPECT_THROW(controls->set_auto_exposure(true), InputError);
  controls->set_locked(false);
  ASSERT_TRUE(wait_for_state(*source, [](const CameraState& s) { return !s.locked; }));
  EXPECT_NO_THROW(controls->set_exposure_ms(20.0));
}

TEST(V4l2Streaming, FrameRateChangeRenegotiates) {
  auto emulator = emulator_with(small_camera());
  emulator->limit_frames("/dev/video0", 0);
  const auto source = open_v4l2_source(spec_for(PixelFormat::Grey), emulator);
  EXPECT_NEAR(source->controls()->state().fps, 30.0, 1e-9);
  EXPECT_EQ(source->controls()->state().rates_fps, (std::vector<double>{30.0, 15.0}));
  source->controls()->set_frame_rate(15.0);
  ASSERT_TRUE(wait_for_state(*source, [](const CameraState& s) { return s.fps == 15.0; }));
  emulator->allow_frames("/dev/video0", 2);  // the device restarted: frames 1/15 s apart
  const auto first = source->next();
  const auto second = source->next();
  ASSERT_TRUE(first && second);
  EXPECT_NEAR(second->timestamp_s - first->timestamp_s, 1.0 / 15.0, 1e-6);
}

}  // namespace
}  // namespace nirslam
