#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/demo_source.hpp"
#include "nirslam/worker/worker.hpp"
#include "counting_source.hpp"
#include "worker/still_rig_sweep.hpp"
#include "opencv_serial_under_tsan.hpp"

namespace nirslam {
namespace {

using namespace std::chrono_literals;

// Worker mechanics are tested with the image-quality stage only: the calibration and odometry
// stages are tested on their own and in PipelineViewsTravelInSnapshots... below, and would make
// these tests minutes long in the sanitiser builds.
WorkerOptions quality_only(WorkerOptions options = {}) {
  options.pipeline.mode = PipelineMode::Quality;
  return options;
}

using testing::CountingOptions;
using testing::CountingSource;

// A counting source (counting_source.hpp); frame `bad_index` is corrupt, frame `bad_type` of
// the wrong pixel type.
SourceFactory counting_factory(int count, double period_s = 0.05, int bad_index = -1, int bad_type = -1) {
  CountingOptions options;
  options.count = count;
  options.period_s = period_s;
  options.wrong_type_index = bad_type;
  if (bad_index >= 0) options.corrupt = {bad_index};
  return [options] { return std::make_unique<CountingSource>(options); };
}

TEST(Worker, StartsIdleWithAnEmptySnapshot) {
  Worker worker(quality_only());
  const auto snapshot = worker.snapshot();
  ASSERT_TRUE(snapshot);
  EXPECT_EQ(snapshot->state, WorkerState::Idle);
  EXPECT_FALSE(snapshot->frame.has_value());
}

TEST(Worker, ProcessesEveryFrameOfADatasetThenFinishes) {
  Worker worker(quality_only({.pacing = Pacing::AsFastAsPossible, .history_length = 10}));
  worker.post(command::SetSource{counting_factory(25)});
  worker.post(command::Start{});
  const auto last = worker.wait_for(settled, 10s);
  ASSERT_EQ(last->state, WorkerState::Finished) << last->message;
  EXPECT_EQ(last->frames_processed, 25);
  ASSERT_TRUE(last->frame);
  EXPECT_EQ(last->frame->index, 24);
  ASSERT_EQ(last->quality_history.size(), 10u);  // bounded
  EXPECT_EQ(last->quality_history.front().frame_index, 15);
  EXPECT_EQ(last->quality_history.back().frame_index, 24);
  EXPECT_EQ(last->source.description, "counting source");
}

TEST(Worker, PauseHoldsAndStepAdvancesExactlyOneFrame) {
  Worker worker(quality_only());
  worker.post(command::SetSource{counting_factory(100)});
  worker.post(command::Step{});
  auto s = worker.wait_for([](const Snapshot& x) { return x.frames_processed == 1; }, 5s);
  ASSERT_EQ(s->frames_processed, 1);
  EXPECT_EQ(s->state, WorkerState::Paused);
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(worker.snapshot()->frames_processed, 1) << "a paused worker must not advance";
  worker.post(command::Step{});
  worker.post(command::Step{});
  s = worker.wait_for([](const Snapshot& x) { return x.frames_processed == 3; }, 5s);
  EXPECT_EQ(s->frames_processed, 3);
  EXPECT_EQ(s->frame->index, 2);
}

TEST(Worker, StopRewindsAndStartBeginsAgain) {
  Worker worker(quality_only());
  worker.post(command::SetSource{counting_factory(5)});
  worker.post(command::Start{});
  ASSERT_EQ(worker.wait_for(settled, 5s)->state, WorkerState::Finished);
  worker.post(command::Stop{});
  worker.post(command::Step{});
  const auto s = worker.wait_for([](const Snapshot& x) { return x.frames_processed == 6; }, 5s);
  ASSERT_TRUE(s->frame);
  EXPECT_EQ(s->frame->index, 0);
}

SourceFactory seekable_counting(int count) {
  CountingOptions options;
  options.count = count;
  options.seekable = true;
  return [options] { return std::make_unique<CountingSource>(options); };
}

TEST(Worker, SeekPausesOnTheFrameJumpedToAndStartGoesOnFromThere) {
  Worker worker(quality_only());
  worker.post(command::SetSource{seekable_counting(100)});
  worker.post(command::Seek{40});
  auto s = worker.wait_for([](const Snapshot& x) { return x.frame && x.frame->index == 40; }, 5s);
  ASSERT_TRUE(s->frame) << s->message;
  EXPECT_EQ(s->frame->index, 40);
  EXPECT_EQ(s->state, WorkerState::Paused);
  EXPECT_EQ(s->frames_processed, 1);
  EXPECT_TRUE(s->source.seekable);
  worker.post(command::Start{});
  s = worker.wait_for(settled, 5s);
  ASSERT_EQ(s->state, WorkerState::Finished) << s->message;
  EXPECT_EQ(s->frames_processed, 60) << "frame 40 and the 59 after it";
  EXPECT_EQ(s->frame->index, 99);
  // Back after the end: the finished run is not restarted from the first frame.
  worker.post(command::Seek{10});
  s = worker.wait_for([](const Snapshot& x) { return x.frame && x.frame->index == 10; }, 5s);
  EXPECT_EQ(s->frame->index, 10);
  EXPECT_EQ(s->state, WorkerState::Paused);
}

TEST(Worker, SeekWhileRunningGoesOnFromTheNewPosition) {
  Worker worker(quality_only({.pacing = Pacing::RecordedSpeed}));
  worker.post(command::SetSource{seekable_counting(400)});  // 20 s of recording at 0.05 s a frame
  worker.post(command::Start{});
  ASSERT_TRUE(worker.wait_for([](const Snapshot& x) { return x.frames_processed >= 2; }, 5s)->frame);
  worker.post(command::Seek{390});
  const auto s = worker.wait_for(settled, 10s);
  ASSERT_EQ(s->state, WorkerState::Finished) << s->message;
  EXPECT_EQ(s->frame->index, 399);
  EXPECT_LT(s->frames_processed, 40) << "the frames between were skipped";
}

TEST(Worker, SeekIsRefusedWithAReasonWhereItCannotBeDone) {
  Worker worker(quality_only());
  worker.post(command::Seek{3});
  EXPECT_NE(worker.wait_for([](const Snapshot& x) { return !x.message.empty(); }, 5s)->message.find("no source"),
            std::string::npos);

  worker.post(command::SetSource{counting_factory(20)});  // not seekable
  worker.post(command::Seek{3});
  auto s = worker.wait_for([](const Snapshot& x) { return x.message.find("cannot jump") != std::string::npos; }, 5s);
  EXPECT_NE(s->message.find("counting source: this source cannot jump"), std::string::npos) << s->message;
  EXPECT_FALSE(s->source.seekable);
  EXPECT_EQ(s->state, WorkerState::Idle);

  worker.post(command::SetSource{seekable_counting(20)});
  worker.post(command::Seek{20});
  s = worker.wait_for([](const Snapshot& x) { return x.message.find("cannot seek") != std::string::npos; }, 5s);
  EXPECT_NE(s->message.find("cannot seek to frame 20, the sequence has 20 frames"), std::string::npos) << s->message;
  EXPECT_EQ(s->state, WorkerState::Idle);
  EXPECT_FALSE(s->frame);
}

TEST(Worker, CorruptFrameFailsWithTheFileNamed) {
  Worker worker(quality_only());
  worker.post(command::SetSource{counting_factory(10, 0.05, 4)});
  worker.post(command::Start{});
  const auto s = worker.wait_for(settled, 5s);
  ASSERT_EQ(s->state, WorkerState::Failed);
  EXPECT_NE(s->message.find("frames/0004.png"), std::string::npos) << s->message;
  EXPECT_EQ(s->frames_processed, 4);
}

TEST(Worker, FrameOfTheWrongPixelTypeFailsInsteadOfBeingMeasured) {
  Worker worker(quality_only());
  worker.post(command::SetSource{counting_factory(10, 0.05, -1, 3)});
  worker.post(command::Start{});
  const auto s = worker.wait_for(settled, 5s);
  ASSERT_EQ(s->state, WorkerState::Failed);
  EXPECT_NE(s->message.find("frame 3"), std::string::npos) << s->message;
}

TEST(Worker, SourceThatCannotOpenReportsWhy) {
  Worker worker(quality_only());
  worker.post(command::SetSource{[]() -> std::unique_ptr<Source> {
    throw InputError("/data/seq/times.txt", 3, "expected 'id timestamp exposure'");
  }});
  const auto s = worker.wait_for([](const Snapshot& x) { return x.state == WorkerState::Failed; }, 5s);
  ASSERT_EQ(s->state, WorkerState::Failed);
  EXPECT_NE(s->message.find("times.txt:3"), std::string::npos) << s->message;
  worker.post(command::Start{});  // nothing to start: stays usable, says so
  const auto after = worker.wait_for([](const Snapshot& x) { return x.message == "no source selected"; }, 5s);
  EXPECT_EQ(after->message, "no source selected");
}

TEST(Worker, RecordedSpeedFollowsTheTimestamps) {
  Worker worker(quality_only({.pacing = Pacing::RecordedSpeed}));
  worker.post(command::SetSource{counting_factory(11, 0.04)});  // 0.4 s of recording
  const auto started = std::chrono::steady_clock::now();
  worker.post(command::Start{});
  ASSERT_EQ(worker.wait_for(settled, 10s)->state, WorkerState::Finished);
  // A lower bound only: a busy machine can make it slower, never faster.
  EXPECT_GE(std::chrono::steady_clock::now() - started, 390ms);
}

TEST(Worker, ObserverSeesEveryFrameBeforeItIsPublished) {
  Worker worker(quality_only());
  std::vector<std::int64_t> seen;  // written on the worker thread only, read after it settles
  worker.set_observer([&seen](const Snapshot& s) { seen.push_back(s.frame->index); });
  worker.post(command::SetSource{counting_factory(30)});
  worker.post(command::Start{});
  ASSERT_EQ(worker.wait_for(settled, 5s)->state, WorkerState::Finished);
  worker.post(command::Pause{});  // round trip through the queue orders the reads below
  worker.wait_for([](const Snapshot&) { return true; }, 1s);
  ASSERT_EQ(seen.size(), 30u);
  for (std::size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], static_cast<std::int64_t>(i));
}

TEST(Worker, ReadersOnOtherThreadsSeeConsistentMonotonicSnapshots) {
  Worker worker(quality_only());
  worker.post(command::SetSource{[] {
    DemoOptions options;
    options.width = 160;
    options.height = 120;
    options.frame_count = 120;
    return make_demo_source(options);
  }});
  worker.post(command::Start{});
  std::atomic<bool> done = false;
  std::atomic<int> violations = 0;
  auto reader = [&] {
    std::uint64_t last_sequence = 0;
    while (!done) {
      const auto s = worker.snapshot();
      if (s->sequence < last_sequence) ++violations;
      last_sequence = s->sequence;
      if (s->frame) {
        // The published frame and its quality belong together and the pixels stay readable.
        const ImageQuality again = measure_quality(*s->frame);
        if (again.entropy_bits != s->quality.entropy_bits) ++violations;
        if (s->quality_history.empty() || s->quality_history.back().frame_index != s->frame->index)
          ++violations;
      }
    }
  };
  std::thread ui_a(reader), ui_b(reader);
  const auto last = worker.wait_for(settled, 20s);
  done = true;
  ui_a.join();
  ui_b.join();
  EXPECT_EQ(last->state, WorkerState::Finished);
  EXPECT_EQ(last->frames_processed, 120);
  EXPECT_EQ(violations, 0);
}

TEST(Worker, DestroyingARunningWorkerStopsPromptly) {
  const auto started = std::chrono::steady_clock::now();
  {
    Worker worker(quality_only({.pacing = Pacing::RecordedSpeed, .loop = true}));
    worker.post(command::SetSource{counting_factory(1000, 1.0)});  // would take 1000 s
    worker.post(command::Start{});
    worker.wait_for([](const Snapshot& s) { return s.frames_processed >= 1; }, 5s);
  }
  EXPECT_LT(std::chrono::steady_clock::now() - started, 5s);
}

TEST(Worker, IlluminatorPowerIsCarriedIntoSnapshots) {
  Worker worker(quality_only());
  worker.post(command::SetIlluminatorPower{80.0});
  const auto s = worker.wait_for([](const Snapshot& x) { return x.illuminator_power_w.has_value(); }, 5s);
  ASSERT_TRUE(s->illuminator_power_w);
  EXPECT_DOUBLE_EQ(*s->illuminator_power_w, 80.0);
}

TEST(Worker, IlluminatorPowerOutsideTheLampsRangeIsRefused) {
  Worker worker(quality_only());  // manual lamp, 0..150 W by default
  worker.post(command::SetIlluminatorPower{60.0});
  worker.post(command::SetIlluminatorPower{400.0});
  const auto s = worker.wait_for(
      [](const Snapshot& x) { return x.message.find("outside the range") != std::string::npos; }, 5s);
  EXPECT_NE(s->message.find("400 W outside the range 0..150 W"), std::string::npos) << s->message;
  ASSERT_TRUE(s->illuminator_power_w);
  EXPECT_DOUBLE_EQ(*s->illuminator_power_w, 60.0) << "the last accepted power stays";
}

TEST(Worker, PublishesEveryFrameMetricAndTheExposureVerdict) {
  Worker worker(quality_only({.pacing = Pacing::AsFastAsPossible, .history_length = 10}));
  DemoOptions demo;
  demo.frame_count = 3;
  worker.post(command::SetSource{[demo] { return make_demo_source(demo); }});
  worker.post(command::Start{});
  const auto last = worker.wait_for(settled, 10s);
  ASSERT_EQ(last->state, WorkerState::Finished) << last->message;
  EXPECT_GT(last->quality.mean, 0.2);
  EXPECT_GT(last->quality.rms_contrast, 0.05);
  EXPECT_GT(last->structure.gradient_energy, 0.0);
  EXPECT_GT(last->structure.feature_count, 50);
  EXPECT_EQ(last->feature_grid.counts.size(), 16u * 12u);
  EXPECT_EQ(last->exposure.verdict, ExposureVerdict::Ok) << last->exposure.message;
  ASSERT_EQ(last->quality_history.size(), 3u);
  EXPECT_EQ(last->quality_history.back().feature_count, last->structure.feature_count);
  EXPECT_FLOAT_EQ(last->quality_history.back().feature_coverage, static_cast<float>(last->structure.coverage));
  ASSERT_TRUE(last->illumination);
  EXPECT_EQ(last->illumination->progress.stage, SweepStage::Idle);
}

// The sweep wizard end to end on the demo, whose virtual lamp follows the power the operator sets:
// every captured power is the power the frames were taken at, the frames get brighter with it,
// and the recommendation comes from the sweep once four powers are in.
TEST(Worker, SweepWizardCapturesEachPowerFromTheDemosLamp) {
  WorkerOptions options = quality_only({.pacing = Pacing::AsFastAsPossible, .loop = true});
  options.illumination.sweep.settle_frames = 1;
  Worker worker(options);
  DemoOptions demo;
  demo.width = 160;
  demo.height = 120;
  worker.post(command::SetSource{[demo] { return make_demo_source(demo); }});
  worker.post(command::Sweep{sweep_command::Start{{0, 25, 50, 100}, 4}});
  worker.post(command::Start{});
  for (const double power : {0.0, 25.0, 50.0, 100.0}) {
    SCOPED_TRACE(power);
    const auto asked = worker.wait_for(
        [&](const Snapshot& s) { return s.illumination && s.illumination->requested_power_w() == power; }, 10s);
    ASSERT_EQ(asked->illumination->requested_power_w(), power) << asked->message;
    worker.post(command::Sweep{sweep_command::Capture{power}});
    const auto captured = worker.wait_for(
        [&](const Snapshot& s) {
          return s.illumination && s.illumination->progress.stage != SweepStage::Capturing &&
                 std::any_of(s.illumination->points.begin(), s.illumination->points.end(),
                             [&](const SweepPoint& p) { return p.power_w == power && p.frames == 4; });
        },
        10s);
    ASSERT_TRUE(captured->frame);
    EXPECT_EQ(captured->frame->illuminator_power_w, power) << "the demo's lamp follows the operator";
  }
  const auto done = worker.wait_for(
      [](const Snapshot& s) { return s.illumination && s.illumination->progress.stage == SweepStage::Complete; }, 10s);
  const IlluminationStatus& status = *done->illumination;
  ASSERT_EQ(status.points.size(), 4u);
  for (std::size_t i = 1; i < status.points.size(); ++i)
    EXPECT_GT(status.points[i].mean.mean, status.points[i - 1].mean.mean) << "brighter with power";
  EXPECT_LT(status.points[0].entropy_bits.mean, status.points[2].entropy_bits.mean);
  EXPECT_EQ(status.recommendation.source, RecommendationSource::Sweep);
  EXPECT_GT(status.recommendation.power_w, 0.0);
  EXPECT_LE(status.recommendation.power_w, 100.0);
}

}  // namespace
}  // namespace nirslam

namespace nirslam {
namespace {

SourceFactory small_simulated(sim::SceneKind scene) {
  return [scene] {
    SimulatorOptions options;
    options.scene = scene;
    options.width = 160;
    options.height = 120;
    options.supersampling = 1;
    options.frames = 6;
    options.exposure_mode = ExposureMode::Fixed;
    return make_simulated_source(options);
  };
}

// The camera's response from the wizard's own sweep in one step: the simulated room with the rig
// on a tripod and the exposure locked; once the sweep is complete the worker fits the response
// from the frames it kept (on a thread of its own, so frames keep flowing), and on request writes
// it and holds it in the pipeline.
TEST(WorkerOnSimulator, PowerSweepGivesTheCameraResponseAndThePipelineHoldsIt) {
  // The sweep needs no pipeline; the calibration comes in for the hold (cheaper under TSan).
  WorkerOptions options = quality_only({.pacing = Pacing::AsFastAsPossible, .loop = true});
  options.illumination.sweep.settle_frames = 1;
  Worker worker(options);
  const SimulatorOptions sim = testing::still_rig();
  const ResponseModel truth = sim.response;
  worker.post(command::SetSource{[sim] { return make_simulated_source(sim); }});
  worker.post(command::Start{});
  testing::sweep_through(worker, {0, 5, 10, 20, 40, 65, 100, 150}, 2);
  if (HasFatalFailure()) return;
  const auto fitted = worker.wait_for(
      [](const Snapshot& s) { return s.sweep_response && s.sweep_response->state != SweepResponse::State::Fitting; },
      60s);
  ASSERT_TRUE(fitted->sweep_response);
  const SweepResponse& response = *fitted->sweep_response;
  ASSERT_EQ(response.state, SweepResponse::State::Done) << response.reason;
  EXPECT_EQ(response.powers_w.size(), 7u);
  EXPECT_EQ(response.images, 16) << "two frames at each of the 8 powers, 0 W (the ambient light) too";
  EXPECT_LT(response.residual_rms_grey, 1.0);
  EXPECT_TRUE(response.warning.empty()) << response.warning;
  double mean = 0.0;
  const std::vector<double> G = response.response.inverse_table(256), G_true = truth.inverse_table(256);
  for (std::size_t i = 0; i < 256; ++i) mean += std::abs(G[i] - G_true[i]) / 256.0;
  std::printf("response from the wizard's sweep: %.2f grey levels mean error, residual %.2f\n", mean,
              response.residual_rms_grey);
  EXPECT_LT(mean, 2.0);

  const auto folder = std::filesystem::temp_directory_path() / "nirslam_worker_sweep_response";
  std::filesystem::remove_all(folder);
  worker.post(command::Pause{});
  worker.post(command::SetPipelineMode{PipelineMode::Calibrated});
  worker.post(command::HoldSweepResponse{folder});
  const auto held = worker.wait_for(
      [](const Snapshot& s) {
        return s.sweep_response && s.sweep_response->held && s.photometric &&
               s.photometric->ambiguity.find("response given") != std::string::npos;
      },
      20s);
  ASSERT_TRUE(held->sweep_response && held->sweep_response->held) << held->message;
  EXPECT_NE(held->photometric->ambiguity.find("response given"), std::string::npos) << held->photometric->ambiguity;
  EXPECT_TRUE(std::filesystem::exists(folder / "pcalib.txt"));
  EXPECT_TRUE(std::filesystem::exists(folder / "sweep_response.json"));

  // Another source may be another camera: it starts without the sweep's response.
  worker.post(command::SetSource{[sim] { return make_simulated_source(sim); }});
  const auto next_source = worker.wait_for(
      [](const Snapshot& s) {
        return !s.sweep_response && s.photometric && !s.photometric->ambiguity.empty() &&
               s.photometric->ambiguity.find("response given") == std::string::npos;
      },
      20s);
  EXPECT_FALSE(next_source->sweep_response);
  ASSERT_TRUE(next_source->photometric);
  EXPECT_EQ(next_source->photometric->ambiguity.find("response given"), std::string::npos)
      << next_source->photometric->ambiguity;
  std::filesystem::remove_all(folder);
}

// A source whose frames report no exposure gives no response, and says why.
TEST(Worker, PowerSweepWithoutReportedExposuresSaysWhy) {
  WorkerOptions options = quality_only({.pacing = Pacing::AsFastAsPossible, .loop = true});
  options.illumination.sweep.settle_frames = 1;
  Worker worker(options);
  CountingOptions endless;
  endless.count = 100000;
  worker.post(command::SetSource{[endless] { return std::make_unique<CountingSource>(endless); }});
  worker.post(command::Start{});
  testing::sweep_through(worker, {25, 50, 100}, 2);
  if (HasFatalFailure()) return;
  const auto done = worker.wait_for(
      [](const Snapshot& s) { return s.sweep_response && s.sweep_response->state != SweepResponse::State::Fitting; },
      20s);
  ASSERT_TRUE(done->sweep_response);
  EXPECT_EQ(done->sweep_response->state, SweepResponse::State::Failed);
  EXPECT_NE(done->sweep_response->reason.find("no exposure"), std::string::npos) << done->sweep_response->reason;
  // Paused, so that the next frame's status does not replace the refusal before it is read.
  worker.post(command::Pause{});
  worker.wait_for([](const Snapshot& s) { return s.state == WorkerState::Paused; }, 10s);
  worker.post(command::HoldSweepResponse{std::filesystem::temp_directory_path() / "nirslam_never_written"});
  const auto refused = worker.wait_for(
      [](const Snapshot& s) { return s.message.find("no camera response") != std::string::npos; }, 10s);
  EXPECT_NE(refused->message.find("no camera response from a complete power sweep"), std::string::npos)
      << refused->message;
}

TEST(WorkerOnSimulator, SimulatedSceneSelectsTheAdvisorsScenePrior) {
  Worker worker(quality_only());
  worker.post(command::SetSource{small_simulated(sim::SceneKind::Parking)});
  const auto s = worker.wait_for(
      [](const Snapshot& x) { return x.illumination && x.illumination->scene() && x.source.kind == "sim"; },
      std::chrono::seconds(10));
  ASSERT_TRUE(s->illumination && s->illumination->scene());
  EXPECT_EQ(s->illumination->scene()->name, "parking");
  EXPECT_EQ(s->source.scene_type, "parking");
}

TEST(WorkerOnSimulator, OperatorPowerDrivesTheSimulatedLamp) {
  Worker worker(quality_only());
  worker.post(command::SetSource{small_simulated(sim::SceneKind::Room)});
  worker.post(command::Step{});
  const auto at_50 = worker.wait_for([](const Snapshot& x) { return x.frames_processed == 1; }, std::chrono::seconds(10));
  ASSERT_TRUE(at_50->frame);
  EXPECT_DOUBLE_EQ(*at_50->frame->illuminator_power_w, 50.0);
  worker.post(command::SetIlluminatorPower{20.0});
  worker.post(command::Step{});
  const auto at_20 = worker.wait_for([](const Snapshot& x) { return x.frames_processed == 2; }, std::chrono::seconds(10));
  ASSERT_TRUE(at_20->frame);
  EXPECT_DOUBLE_EQ(*at_20->frame->illuminator_power_w, 20.0);
  EXPECT_LT(at_20->quality.mean, at_50->quality.mean) << "less light, darker image at fixed exposure";
}


// The whole pipeline in the worker: corrected frames, the photometric and trajectory views in
// every snapshot, the finish handler with the final state, and a mode switch that restarts the
// stages. Small frames, so ThreadSanitizer runs it in reasonable time.
TEST(WorkerOnSimulator, PipelineViewsTravelInSnapshotsAndTheFinishHandlerSeesTheEnd) {
  WorkerOptions options;
  options.pipeline.mode = PipelineMode::Calibrated;
  // The odometry waits for the back end's first fitted model, by default up to 30 frames; on a
  // busy machine the back end's thread may fit none within these 20 (a CI run saw no tracking
  // at all), so the wait is short enough that the odometry always gets frames.
  options.pipeline.odometry_waits_for_model_frames = 4;
  Worker worker(options);
  std::atomic<std::size_t> final_poses{0};
  std::atomic<bool> finished_with_calibration{false};
  worker.set_finish_handler([&](const SlamPipeline& pipeline) {
    if (pipeline.odometry()) final_poses = pipeline.odometry()->trajectory().size();
    finished_with_calibration = pipeline.calibration() != nullptr;
  });
  worker.post(command::SetSource{[] {
    SimulatorOptions sim;
    sim.scene = sim::SceneKind::Room;
    sim.width = 192;
    sim.height = 144;
    sim.supersampling = 1;
    sim.frames = 20;
    return make_simulated_source(sim);
  }});
  worker.post(command::Start{});
  const auto done = worker.wait_for([](const Snapshot& x) { return x.state == WorkerState::Finished || x.state == WorkerState::Failed; },
                                    std::chrono::seconds(300));
  ASSERT_EQ(done->state, WorkerState::Finished) << done->message;
  EXPECT_EQ(done->frames_processed, 20);
  EXPECT_EQ(done->pipeline_mode, "calibrated");
  ASSERT_TRUE(done->photometric && done->trajectory);
  EXPECT_TRUE(done->photometric->enabled);
  EXPECT_TRUE(done->photometric->true_response.has_value()) << "the simulator's truth is overlaid";
  EXPECT_EQ(done->photometric->exposures.size(), 20u);
  // The exposure advice comes with the estimate whose samples stop short of the top, and names its top.
  const PhotometricView& photometric = *done->photometric;
  const bool stops_short = photometric.model_version > 0 && photometric.grey_high > photometric.grey_low &&
                           photometric.grey_high < kOnlineAdvisedHighestGrey;
  EXPECT_EQ(photometric.range_advice.has_value(), stops_short) << photometric.grey_high;
  if (photometric.range_advice) {
    EXPECT_EQ(photometric.range_advice->highest_grey, photometric.grey_high);
  }
  EXPECT_TRUE(done->trajectory->enabled);
  EXPECT_FALSE(done->trajectory->tracking.empty());
  EXPECT_TRUE(finished_with_calibration.load());
  EXPECT_EQ(final_poses.load(), done->trajectory->poses.size());
  ASSERT_TRUE(done->frame.has_value());
  EXPECT_TRUE(done->frame->T_world_cam_truth.has_value());

  worker.post(command::SetPipelineMode{PipelineMode::Quality});
  const auto quality = worker.wait_for([](const Snapshot& x) { return x.pipeline_mode == "quality"; }, std::chrono::seconds(10));
  EXPECT_EQ(quality->pipeline_mode, "quality");
  EXPECT_FALSE(quality->photometric->enabled);
  EXPECT_FALSE(quality->trajectory->enabled);
  EXPECT_TRUE(quality->corrected_image.empty());
}

// The automatic mode: the lamp's model for a source that reports its lamp, calibration alone for
// one that does not; a named mode ends it until "automatic" is asked for again.
TEST(Worker, AutomaticModeFollowsTheSourcesLamp) {
  const auto sim_at = [](double power_w) {
    return [power_w] {
      SimulatorOptions sim;
      sim.scene = sim::SceneKind::Room;
      sim.width = 192;
      sim.height = 144;
      sim.supersampling = 1;
      sim.frames = 5;
      sim.powers_w = {power_w};
      return make_simulated_source(sim);
    };
  };
  WorkerOptions options;
  options.pipeline_mode_automatic = true;
  options.pipeline.mode = PipelineMode::Odometry;  // replaced by the automatic choice
  Worker worker(options);
  const auto source_ready = [](const std::string& mode) {
    return [mode](const Snapshot& x) { return x.source.kind == "sim" && x.pipeline_mode == mode; };
  };

  worker.post(command::SetSource{sim_at(50.0)});
  auto lit = worker.wait_for(source_ready("illuminated"), std::chrono::seconds(30));
  EXPECT_EQ(lit->pipeline_mode, "illuminated");
  EXPECT_TRUE(lit->pipeline_mode_automatic);
  EXPECT_TRUE(lit->source.reports_lamp_power);

  worker.post(command::SetSource{sim_at(0.0)});
  auto dark = worker.wait_for(
      [](const Snapshot& x) { return x.source.kind == "sim" && !x.source.reports_lamp_power && x.pipeline_mode == "calibrated"; },
      std::chrono::seconds(30));
  EXPECT_EQ(dark->pipeline_mode, "calibrated");
  EXPECT_TRUE(dark->pipeline_mode_automatic);

  worker.post(command::SetPipelineMode{PipelineMode::Odometry});
  auto named = worker.wait_for([](const Snapshot& x) { return x.pipeline_mode == "odometry"; }, std::chrono::seconds(10));
  EXPECT_EQ(named->pipeline_mode, "odometry");
  EXPECT_FALSE(named->pipeline_mode_automatic);
  worker.post(command::SetSource{sim_at(50.0)});
  named = worker.wait_for([](const Snapshot& x) { return x.source.reports_lamp_power; }, std::chrono::seconds(30));
  EXPECT_EQ(named->pipeline_mode, "odometry") << "a named mode stays when the source changes";

  worker.post(command::SetPipelineMode{std::nullopt});
  const auto again = worker.wait_for([](const Snapshot& x) { return x.pipeline_mode_automatic; }, std::chrono::seconds(10));
  EXPECT_EQ(again->pipeline_mode, "illuminated");
  EXPECT_NE(again->message.find("automatic"), std::string::npos) << again->message;
}

}  // namespace
}  // namespace nirslam
