// The V4L2 source under threads (these tests also run under ThreadSanitizer): the worker pulls
// frames from an emulated camera on its thread while a "GUI" thread reads the camera state and
// moves exposure and gain, the capture thread applies them, and an unplug ends the run with every
// captured frame either processed or counted as dropped.

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>

#include "nirslam/capture/emulated_uvc.hpp"
#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/worker/worker.hpp"

namespace nirslam {
namespace {

using namespace std::chrono_literals;

std::shared_ptr<EmulatedUvc> paced_camera(int frames_before_unplug) {
  auto emulator = std::make_shared<EmulatedUvc>();
  EmulatedCameraSpec camera = emulated_mono_nir_camera("/dev/video0");
  camera.formats = {{PixelFormat::Y10, {{64, 48}}, {60.0}}};
  camera.paced = true;
  emulator->add_camera(camera);
  emulator->unplug_after("/dev/video0", frames_before_unplug);
  return emulator;
}

TEST(V4l2SourceThreads, WorkerRunsALiveCameraWhileTheGuiMovesItsControls) {
  constexpr int kFrames = 24;
  auto emulator = paced_camera(kFrames);
  std::mutex mutex;
  std::shared_ptr<CameraControls> controls;  // published by the factory on the worker thread

  WorkerOptions options;
  options.pipeline.mode = PipelineMode::Quality;
  options.pacing = Pacing::AsFastAsPossible;
  Worker worker(options);
  worker.post(command::SetSource{[&]() -> std::unique_ptr<Source> {
    V4l2SourceSpec spec;
    spec.format = PixelFormat::Y10;
    spec.queue_capacity = 2;
    spec.reconnect_wait_s = 0.1;
    auto source = open_v4l2_source(spec, emulator);
    const std::lock_guard lock(mutex);
    controls = source->controls();
    return source;
  }});
  worker.post(command::Start{});

  std::atomic<bool> done{false};
  std::atomic<int> refused{0};
  std::thread gui([&] {
    int step = 0;
    while (!done) {
      std::shared_ptr<CameraControls> c;
      {
        const std::lock_guard lock(mutex);
        c = controls;
      }
      if (c) {
        const CameraState state = c->state();  // what the panel draws every UI frame
        EXPECT_EQ(state.device, "/dev/video0");
        try {
          c->set_exposure_ms(1.0 + (step % 20));
          c->set_gain(10 + step % 30);
        } catch (const InputError&) {
          ++refused;  // the device went away: the controls say so instead of crashing
        }
        ++step;
      }
      std::this_thread::sleep_for(2ms);
    }
  });

  const auto last = worker.wait_for([](const Snapshot& s) {
    return s.state == WorkerState::Finished || s.state == WorkerState::Failed;
  }, 20s);
  done = true;
  gui.join();
  ASSERT_EQ(last->state, WorkerState::Finished) << last->message;
  ASSERT_TRUE(controls);
  const CameraState state = controls->state();
  EXPECT_EQ(state.frames_captured, kFrames);
  // Every captured frame was processed or dropped from the queue, and the snapshot counts drops.
  EXPECT_EQ(last->frames_processed + state.frames_dropped_by_queue, kFrames);
  EXPECT_EQ(last->frames_dropped, state.frames_dropped_by_driver + state.frames_dropped_by_queue);
  EXPECT_EQ(state.connection, CameraConnection::Unplugged);
  EXPECT_NE(state.message.find("unplugged after 24 frames"), std::string::npos) << state.message;
  EXPECT_EQ(last->message, state.message) << "the worker says why the stream ended, not just that it did";
  ASSERT_TRUE(last->frame.has_value());
  ASSERT_TRUE(last->frame->exposure_ms.has_value());
  EXPECT_GE(*last->frame->exposure_ms, 1.0);
  EXPECT_EQ(refused.load(), 0);
}

TEST(V4l2SourceThreads, DestroyingTheSourceWhileItWaitsForAFrameReturnsPromptly) {
  auto emulator = paced_camera(1000);
  emulator->hold_frames("/dev/video0", true);  // no frame ever becomes ready
  V4l2SourceSpec spec;
  auto source = open_v4l2_source(spec, emulator);
  const auto started = std::chrono::steady_clock::now();
  source.reset();  // joins the capture thread, which is waiting in poll
  EXPECT_LT(std::chrono::steady_clock::now() - started, 2s);
}

}  // namespace
}  // namespace nirslam
