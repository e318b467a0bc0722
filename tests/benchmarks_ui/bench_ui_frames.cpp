// UI frame cost, rendered offscreen through EGL exactly as the window renders (Mesa llvmpipe on
// this machine): the whole layout on a snapshot as the worker publishes it mid-run, and the 3-D
// view alone with up to 100k map points. Each iteration is one UI frame finished on the GPU
// (glFinish), in wall time: llvmpipe rasterises on its own threads, which CPU time would miss.
//
//   build/nirslam_ui_benchmarks                       # all
//   build/nirslam_ui_benchmarks --benchmark_filter=ThreeD
//
// The figure that matters is frames per second = 1000 / (ms per iteration); the target is 60.

#include <cmath>
#include <memory>
#include <random>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "frontends/egl_context.hpp"
#include "nirslam/quality/image_quality.hpp"
#include "nirslam/worker/snapshot.hpp"
#include "ui/application.hpp"
#include "ui/gl/gl.hpp"
#include "ui/gl/shader.hpp"
#include "ui/ui_context.hpp"

namespace nirslam::ui {
namespace {

Frame textured_frame() {
  Frame frame;
  frame.image = cv::Mat(480, 640, CV_8UC1);
  cv::randu(frame.image, 0, 255);
  cv::GaussianBlur(frame.image, frame.image, cv::Size(0, 0), 2.0);
  frame.index = 1200;
  frame.timestamp_s = 40.0;
  frame.exposure_ms = 8.0;
  frame.illuminator_power_w = 50.0;
  return frame;
}

// A snapshot as the worker publishes it 40 s into a run of the full pipeline: a frame, 300
// samples of history, the photometric estimate with 600 exposures, and a trajectory of 1200
// poses, 60 keyframes and `points` map points.
Snapshot busy_snapshot(int points) {
  Snapshot s;
  s.sequence = 1200;
  s.state = WorkerState::Running;
  s.source.kind = "sim";
  s.source.description = "simulated pipe tunnel";
  s.source.frame_count = 3000;
  Frame frame = textured_frame();
  s.quality = measure_quality(frame, &s.histogram);
  for (int i = 0; i < 300; ++i) {
    QualitySample q;
    q.frame_index = 900 + i;
    q.quality = s.quality;
    q.quality.entropy_bits = 6.5 + 0.5 * std::sin(i / 17.0);
    s.quality_history.push_back(q);
  }
  s.frames_processed = 1200;
  s.processing_fps = 24.0;
  s.frame = std::move(frame);
  s.corrected_image = cv::Mat(480, 640, CV_32FC1, cv::Scalar(0.5f));
  s.pipeline_mode = "calibrated";

  auto photometric = std::make_shared<PhotometricView>();
  photometric->enabled = true;
  photometric->response = ResponseModel::from_preset(ResponsePreset::Gamma);
  photometric->vignette = VignetteModel{Eigen::Vector3d(-0.3, 0.05, -0.02)};
  photometric->true_response = ResponseModel::from_preset(ResponsePreset::Gamma);
  photometric->true_vignette = VignetteModel{Eigen::Vector3d(-0.3, 0.0, 0.0)};
  photometric->converged = true;
  for (int i = 0; i < 600; ++i) {
    ExposurePoint p;
    p.frame_index = 600 + i;
    p.timestamp_s = (600 + i) / 30.0;
    p.estimated = static_cast<float>(8.0 + 2.0 * std::sin(i / 40.0));
    p.reference = p.estimated * 1.01f;
    p.keyframe = i % 20 == 0;
    photometric->exposures.push_back(p);
  }
  s.photometric = photometric;

  auto trajectory = std::make_shared<TrajectoryView>();
  trajectory->enabled = true;
  trajectory->tracking = "tracking";
  trajectory->aligned_to_ground_truth = true;
  for (int i = 0; i < 1200; ++i) {
    PoseSample p;
    p.frame_index = i;
    const float t = static_cast<float>(i) / 1200.0f * 6.28f;
    p.position = Eigen::Vector3f(10.0f * std::cos(t), 0.2f * std::sin(3.0f * t), 10.0f * std::sin(t));
    p.error_m = 0.05f * std::abs(std::sin(t));
    trajectory->poses.push_back(p);
    trajectory->ground_truth.push_back(p.position + Eigen::Vector3f(0.02f, 0.0f, 0.0f));
    if (i % 20 == 0) trajectory->keyframes.push_back(p);
  }
  trajectory->current = trajectory->poses.back();
  auto cloud = std::make_shared<std::vector<MapPointSample>>();
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < points; ++i) {
    const float t = 3.1416f * u(rng);
    const float r = 11.5f + 0.5f * u(rng);
    cloud->push_back({Eigen::Vector3f(r * std::cos(t), 1.5f * u(rng), r * std::sin(t)), 128.0f + 100.0f * u(rng),
                      i % 10 == 0});
  }
  trajectory->points = cloud;
  for (int i = 0; i < 1500; ++i) {
    trajectory->current_pixels.emplace_back(320.0f + 300.0f * u(rng), 240.0f + 220.0f * u(rng));
    trajectory->current_depths.push_back(2.0f + u(rng));
  }
  s.trajectory = trajectory;
  return s;
}

// `fresh_every_frame`: every UI frame gets a snapshot with a new frame and a new trajectory view
// (the worst case: the worker publishing at the UI's rate), so the feed and the 3-D view render
// their targets anew each time. Otherwise the snapshot stays (the UI between two worker frames).
void run_frames(benchmark::State& state, int width, int height, PanelSet panels, int points, bool fresh_every_frame) {
  app::EglContext egl;
  OffscreenUi offscreen(width, height);
  Application app(gl::find_shader_dir(), {});
  app.panels = panels;
  Snapshot snapshots[2] = {busy_snapshot(points), busy_snapshot(0)};
  snapshots[1] = snapshots[0];
  snapshots[1].frame->image = snapshots[0].frame->image.clone();
  snapshots[1].trajectory = std::make_shared<TrajectoryView>(*snapshots[0].trajectory);
  for (int i = 0; i < 5; ++i) offscreen.frame([&] { app.draw(snapshots[0]); });  // fonts, buffers, shaders
  glFinish();
  std::size_t n = 0;
  for (auto _ : state) {
    const Snapshot& shown = snapshots[fresh_every_frame ? n++ % 2 : 0];
    offscreen.frame([&] { app.draw(shown); });
    glFinish();
  }
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

PanelSet nothing() { return PanelSet{false, false, false, false, false, false, false, false}; }

// Args: map points, new snapshot every frame (1) or not (0).
void BM_UiFrame_WholeLayout(benchmark::State& state) {
  run_frames(state, 1280, 800, PanelSet{}, static_cast<int>(state.range(0)), state.range(1) != 0);
}
BENCHMARK(BM_UiFrame_WholeLayout)
    ->ArgsProduct({{20000, 100000}, {0, 1}})
    ->ArgNames({"points", "fresh"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_UiFrame_ThreeDViewAlone(benchmark::State& state) {
  PanelSet only = nothing();
  only.view3d = true;
  run_frames(state, 1280, 800, only, static_cast<int>(state.range(0)), state.range(1) != 0);
}
BENCHMARK(BM_UiFrame_ThreeDViewAlone)
    ->ArgsProduct({{20000, 100000}, {0, 1}})
    ->ArgNames({"points", "fresh"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_UiFrame_FeedAlone(benchmark::State& state) {
  PanelSet only = nothing();
  only.feed = true;
  run_frames(state, 1280, 800, only, 0, state.range(0) != 0);
}
BENCHMARK(BM_UiFrame_FeedAlone)->Arg(0)->Arg(1)->ArgName("fresh")->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace nirslam::ui


namespace nirslam::ui {
namespace {

// The floor: an empty UI frame (clear, no window) at the same size, for reading the others.
void BM_UiFrame_Empty(benchmark::State& state) { run_frames(state, 1280, 800, nothing(), 0, false); }
BENCHMARK(BM_UiFrame_Empty)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace nirslam::ui

BENCHMARK_MAIN();
