// Kernel benchmarks: run `build/nirslam_benchmarks` (Release). Figures go in the README.
#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "nirslam/quality/image_quality.hpp"
#include "nirslam/sources/demo_source.hpp"

namespace {

void BM_MeasureQuality8Bit(benchmark::State& state) {
  cv::Mat image(static_cast<int>(state.range(1)), static_cast<int>(state.range(0)), CV_8UC1);
  cv::randu(image, 0, 256);
  for (auto _ : state) benchmark::DoNotOptimize(nirslam::measure_quality(image, 8));
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(image.total()));
}
BENCHMARK(BM_MeasureQuality8Bit)->Args({640, 480})->Args({752, 480})->Args({1280, 1024});

void BM_MeasureQuality16Bit(benchmark::State& state) {
  cv::Mat image(480, 640, CV_16UC1);
  cv::randu(image, 0, 4096);
  for (auto _ : state) benchmark::DoNotOptimize(nirslam::measure_quality(image, 12));
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(image.total()));
}
BENCHMARK(BM_MeasureQuality16Bit);

void BM_DemoSourceFrame(benchmark::State& state) {
  nirslam::DemoOptions options;
  options.frame_count = 0;  // endless
  auto source = nirslam::make_demo_source(options);
  for (auto _ : state) benchmark::DoNotOptimize(source->next());
}
BENCHMARK(BM_DemoSourceFrame)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
