// Direct odometry benchmark: run `build/nirslam_benchmarks --benchmark_filter=Odometry` (Release).
// The target: at least 20 frames/s at 640x480 on 2 cores. One iteration is one
// process() call on a pre-rendered simulated sequence (the tunnel, hand-held, 50 W); at the end of
// the sequence the odometry is reset (outside the timing) and the sequence replayed. Counters:
// mean per-frame milliseconds per stage, mapping per keyframe, the keyframe share. The second
// argument turns the co-located lamp's factor on (1/d^2, the simulator's beam, cos(theta) from
// fitted normals, the frames' power), to measure its cost.
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "nirslam/odometry/direct_odometry.hpp"
#include "nirslam/sim/simulator.hpp"

namespace {

void BM_OdometryProcess(benchmark::State& state) {
  nirslam::SimulatorOptions o;
  o.scene = static_cast<nirslam::sim::SceneKind>(state.range(0));
  o.width = 640;
  o.height = 480;
  o.supersampling = 1;
  o.frames = 150;
  nirslam::Simulator sim(o);
  std::vector<nirslam::OdometryFrame> frames;
  while (auto f = sim.next()) {  // rendered before timing
    nirslam::OdometryFrame frame;
    frame.frame_index = f->frame.index;
    frame.timestamp_s = f->frame.timestamp_s;
    f->frame.image.convertTo(frame.image, CV_32F);
    frame.illuminator_power_w = f->frame.illuminator_power_w;
    frames.push_back(std::move(frame));
  }
  const auto camera = nirslam::make_sim_camera(o);
  const nirslam::PinholeCamera pinhole(camera->width(), camera->height(), camera->intrinsics());
  nirslam::OdometryOptions options;
  options.illuminator_correction = state.range(1) != 0;
  options.beam_exponent = options.illuminator_correction ? 4.82 : 0.0;  // the simulator's 30 degree beam
  nirslam::DirectOdometry odometry(pinhole, options);

  std::size_t i = 0;
  double pyramid = 0.0, tracking = 0.0, mapping = 0.0, total = 0.0;
  int keyframes = 0;
  int lost = 0;
  for (auto _ : state) {
    if (i == frames.size()) {
      state.PauseTiming();
      i = 0;
      odometry.reset();
      state.ResumeTiming();
    }
    const nirslam::OdometryResult r = odometry.process(frames[i++]);
    pyramid += r.timings.pyramid_ms;
    tracking += r.timings.tracking_ms;
    mapping += r.timings.mapping_ms;
    total += r.timings.total_ms;
    keyframes += r.is_keyframe ? 1 : 0;
    lost += r.status == nirslam::TrackingStatus::Lost ? 1 : 0;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["pyramid_ms"] = pyramid / n;
  state.counters["tracking_ms"] = tracking / n;
  state.counters["mapping_ms"] = mapping / n;
  state.counters["mapping_ms_per_kf"] = keyframes > 0 ? mapping / keyframes : 0.0;
  state.counters["total_ms"] = total / n;
  state.counters["keyframe_share"] = keyframes / n;
  state.counters["lost"] = lost;
  state.counters["fps"] = benchmark::Counter(n, benchmark::Counter::kIsRate);
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(std::string(nirslam::sim::to_string(o.scene)) + " 640x480, 2 threads in the window" +
                 (options.illuminator_correction ? ", lamp factor" : ""));
}
BENCHMARK(BM_OdometryProcess)
    ->Args({static_cast<int>(nirslam::sim::SceneKind::Tunnel), 0})
    ->Args({static_cast<int>(nirslam::sim::SceneKind::Tunnel), 1})
    ->Args({static_cast<int>(nirslam::sim::SceneKind::Room), 0})
    ->Args({static_cast<int>(nirslam::sim::SceneKind::Room), 1})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(450);

}  // namespace
