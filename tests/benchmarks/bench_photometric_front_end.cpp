// Photometric front end benchmark: run `build/nirslam_benchmarks --benchmark_filter=Photometric`
// (Release). The target: gain-robust KLT tracking plus the exposure estimate under 10 ms
// per frame at 640x480 on one core; OpenCV is set to one thread here, but the tracker follows its
// patches on two threads, so the one-core figure is `taskset -c 0 build/nirslam_benchmarks ...`.
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "nirslam/photometric/exposure_estimator.hpp"
#include "nirslam/photometric/photometric_tracker.hpp"
#include "nirslam/sim/simulator.hpp"

namespace {

void BM_PhotometricFrontEnd(benchmark::State& state) {
  cv::setNumThreads(0);
  nirslam::SimulatorOptions o;
  o.scene = nirslam::sim::SceneKind::Room;
  o.width = 640;
  o.height = 480;
  o.supersampling = 1;
  o.frames = 60;
  o.exposure_ms = 3.0;
  nirslam::Simulator sim(o);
  std::vector<nirslam::Frame> frames;
  while (auto f = sim.next()) frames.push_back(f->frame);  // rendered before timing

  // Arg 1: each track's first patch aligned under an affine warp after its frame-to-frame step
  // (PhotometricTrackerOptions::align_reference_affine).
  nirslam::PhotometricTrackerOptions tracker_options;
  tracker_options.align_reference_affine = state.range(0) != 0;
  nirslam::PhotometricTracker tracker(tracker_options);
  nirslam::ExposureEstimator estimator(o.response, o.vignette);
  std::size_t i = 0;
  int tracks = 0;
  for (auto _ : state) {
    if (i == frames.size()) {  // loop the sequence: restart tracking (a jump, not a cut-off tail)
      state.PauseTiming();
      i = 0;
      tracker.reset();
      estimator.reset();
      state.ResumeTiming();
    }
    const auto& tracked = tracker.process(frames[i++]);
    benchmark::DoNotOptimize(estimator.update(tracked));
    tracks = static_cast<int>(tracked.tracks.size());
  }
  state.counters["tracks"] = tracks;
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(state.range(0) != 0 ? "640x480, OpenCV 1 thread, patches on 2, affine to the first patch"
                                     : "640x480, OpenCV 1 thread, patches on 2");
}
BENCHMARK(BM_PhotometricFrontEnd)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
