// Online photometric calibration: per-frame process() (front end: tracking, exposure, corrected
// image) at 640x480, and one back-end update (add a keyframe + LM iterations over the window).
#include <benchmark/benchmark.h>

#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam {
namespace {

std::vector<Frame> room_frames(int n) {
  SimulatorOptions o;
  o.scene = sim::SceneKind::Room;
  o.frames = n;
  o.exposure_ms = 2.0;
  o.powers_w = {0.0};
  o.ambient_irradiance = 0.4;
  Simulator sim(o);
  std::vector<Frame> frames;
  while (auto f = sim.next()) frames.push_back(f->frame);
  return frames;
}

void BM_PhotometricOnlineProcess640(benchmark::State& state) {
  static const std::vector<Frame> frames = room_frames(60);
  OnlineCalibrationOptions options;
  options.run_backend = false;  // the caller's thread only
  // Arg 1: the keyframes' observations follow the surface (the tracker fits each track's deformation).
  options.keyframes_follow_deformation = state.range(0) != 0;
  OnlinePhotometricCalibration calibration(options);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(calibration.process(frames[i % frames.size()]));
    if (++i % frames.size() == 0) calibration.reset();
  }
}
BENCHMARK(BM_PhotometricOnlineProcess640)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Keyframes from the front end, then time one update (4 LM iterations over a 40-keyframe window).
void time_backend_updates(benchmark::State& state, const OnlineCalibrationOptions& options) {
  static const std::vector<Frame> frames = room_frames(120);
  PhotometricTracker tracker;
  ExposureEstimator estimator(options.backend.initial_response, options.backend.initial_vignette);
  std::vector<PhotometricKeyframe> keyframes;
  for (const Frame& f : frames) {
    const TrackedFrame& t = tracker.process(f);
    const ExposureEstimate& e = estimator.update(t);
    if (e.updated()) keyframes.push_back(make_photometric_keyframe(t, f.timestamp_s, *f.exposure_ms, true));
  }
  PhotometricBackend backend(options.backend);
  std::size_t i = 0;
  for (; i < 40; ++i) backend.add_keyframe(keyframes[i]);
  backend.optimise(20);
  int rejected = 0, updates = 0;
  for (auto _ : state) {
    backend.add_keyframe(keyframes[i++ % keyframes.size()]);
    const BackendStep step = backend.optimise(options.iterations_per_keyframe);
    rejected += step.points_rejected;
    ++updates;
    benchmark::DoNotOptimize(step);
  }
  state.counters["points_rejected"] = updates > 0 ? static_cast<double>(rejected) / updates : 0.0;
}

// Without (0) and with (1, the default) the straight rim of V.
void BM_PhotometricBackendUpdate(benchmark::State& state) {
  OnlineCalibrationOptions options;
  options.backend.vignette_rim_curvature_weight = static_cast<double>(state.range(0));
  time_backend_updates(state, options);
}
BENCHMARK(BM_PhotometricBackendUpdate)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The default, with inconsistent points left out at this many robust standard deviations (the
// solve continues without them: up to twice the LM iterations when any go).
void BM_PhotometricBackendUpdateLeavingOutPoints(benchmark::State& state) {
  OnlineCalibrationOptions options;
  options.backend.point_rejection_sigmas = static_cast<double>(state.range(0));
  time_backend_updates(state, options);
}
BENCHMARK(BM_PhotometricBackendUpdateLeavingOutPoints)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace nirslam
