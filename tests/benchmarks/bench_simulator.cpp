// Simulator benchmarks: run `build/nirslam_benchmarks --benchmark_filter=Sim` (Release). The
// issue's target: at least 30 frames/s at 640x480 with 2x2 supersampling on 2 cores. Frames/s is
// the items_per_second column (wall time: rendering runs on OpenCV's thread pool).
#include <span>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "nirslam/sim/simulator.hpp"

namespace {

using nirslam::sim::SceneKind;

nirslam::SimulatorOptions options_for(int scene, int supersampling) {
  nirslam::SimulatorOptions o;
  o.scene = static_cast<SceneKind>(scene);
  o.supersampling = supersampling;
  o.frames = 0;  // endless
  return o;
}

void label(benchmark::State& state) {
  state.SetLabel(std::string(nirslam::sim::to_string(static_cast<SceneKind>(state.range(0)))) + " ss" +
                 std::to_string(state.range(1)) + " threads " + std::to_string(cv::getNumThreads()));
}

// A whole frame as the Source delivers it: ray casting, sensor model, auto exposure.
void BM_SimFrame(benchmark::State& state) {
  nirslam::Simulator sim(options_for(static_cast<int>(state.range(0)), static_cast<int>(state.range(1))));
  for (auto _ : state) benchmark::DoNotOptimize(sim.next());
  state.SetItemsProcessed(state.iterations());
  label(state);
}
BENCHMARK(BM_SimFrame)
    ->ArgsProduct({{0, 1, 2, 3}, {2}})
    ->Args({3, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Ray casting and shading only.
void BM_SimRender(benchmark::State& state) {
  nirslam::Simulator sim(options_for(static_cast<int>(state.range(0)), static_cast<int>(state.range(1))));
  cv::Mat radiance;
  double t = 0.0;
  for (auto _ : state) {
    sim.render_radiance(t, 10.0, 50.0, radiance);
    t += 1.0 / 30.0;
  }
  state.SetItemsProcessed(state.iterations());
  label(state);
}
BENCHMARK(BM_SimRender)->ArgsProduct({{0, 3}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();

// The sensor model alone: noise, response, quantisation.
void BM_SimExpose(benchmark::State& state) {
  nirslam::Simulator sim(options_for(3, 2));
  cv::Mat radiance;
  sim.render_radiance(1.0, 10.0, 50.0, radiance);
  std::uint64_t key = 0;
  for (auto _ : state) benchmark::DoNotOptimize(sim.expose(radiance, 10.0, 1.0, ++key));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SimExpose)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
