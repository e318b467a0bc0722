// Kernel benchmarks: run `build/nirslam_benchmarks` (Release). Figures go in the README.
#include <filesystem>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/illumination/advisor.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/quality/frame_metrics.hpp"
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

// A real 640x480 frame (ViSP's textured cube, hand-held): natural statistics for FAST. Falls back to
// a demo frame when the Debian package is not installed.
cv::Mat real_vga_frame() {
  cv::Mat image;
  try {
    image = nirslam::read_image("/usr/share/visp-images-data/ViSP-images/mbt/cube/image0000.pgm", nirslam::ImageReadMode::Grey);
  } catch (const std::runtime_error&) {
  }
  if (image.empty() || image.size() != cv::Size(640, 480)) {
    nirslam::DemoOptions options;
    image = nirslam::make_demo_source(options)->next()->image;
  }
  return image;
}

// Every per-frame metric at 640x480 on one core: histogram pass (entropy, clipping, mean, RMS
// contrast), gradient energy, FAST corners with grid coverage and evenness. The worker runs this on
// every frame; the target is well under 5 ms.
void BM_FrameMetricsVga(benchmark::State& state) {
  cv::setNumThreads(1);
  const cv::Mat image = real_vga_frame();
  nirslam::QualityMeter meter;
  nirslam::GreyHistogram histogram;
  nirslam::FeatureGrid grid;
  int corners = 0;
  for (auto _ : state) {
    const nirslam::FrameMetrics m = meter.measure(image, 8, &histogram, &grid);
    corners = m.structure.feature_count;
    benchmark::DoNotOptimize(m);
  }
  state.counters["corners"] = corners;
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(image.total()));
}
BENCHMARK(BM_FrameMetricsVga)->Unit(benchmark::kMillisecond);

// The same on the demo's noisy frames (more corners) and on 12-bit data.
void BM_FrameMetricsVgaDemo(benchmark::State& state) {
  cv::setNumThreads(1);
  nirslam::DemoOptions options;
  const cv::Mat image = nirslam::make_demo_source(options)->next()->image;
  nirslam::QualityMeter meter;
  for (auto _ : state) benchmark::DoNotOptimize(meter.measure(image, 8));
}
BENCHMARK(BM_FrameMetricsVgaDemo)->Unit(benchmark::kMillisecond);

void BM_FrameMetricsVga12Bit(benchmark::State& state) {
  cv::setNumThreads(1);
  cv::Mat image;
  real_vga_frame().convertTo(image, CV_16UC1, 16.0);
  nirslam::QualityMeter meter;
  for (auto _ : state) benchmark::DoNotOptimize(meter.measure(image, 12));
}
BENCHMARK(BM_FrameMetricsVga12Bit)->Unit(benchmark::kMillisecond);

// The parts alone.
void BM_GradientEnergyVga(benchmark::State& state) {
  const cv::Mat image = real_vga_frame();
  for (auto _ : state) benchmark::DoNotOptimize(nirslam::gradient_energy(image, 8));
}
BENCHMARK(BM_GradientEnergyVga);

void BM_FastCornersVga(benchmark::State& state) {
  cv::setNumThreads(1);
  const cv::Mat image = real_vga_frame();
  std::vector<cv::KeyPoint> corners;
  for (auto _ : state) {
    corners.clear();
    cv::FAST(image, corners, 20, true);
    benchmark::DoNotOptimize(corners.data());
  }
}
BENCHMARK(BM_FastCornersVga);

// The advisor on an 8-power sweep (fit and recommendation): run once per completed power.
void BM_RecommendFromSweep(benchmark::State& state) {
  const nirslam::SaturationCurve curve{2.0, 7.5, 20.0};
  std::vector<nirslam::SweepPoint> points;
  for (double p : {0.0, 20.0, 40.0, 50.0, 70.0, 100.0, 125.0, 150.0}) {
    nirslam::SweepPoint point;
    point.power_w = p;
    nirslam::FrameMetrics m;
    m.quality.entropy_bits = curve(p) + 0.01 * std::sin(p);
    point.add(m);
    points.push_back(point);
  }
  for (auto _ : state) benchmark::DoNotOptimize(nirslam::recommend_from_sweep(points, {}, {}));
}
BENCHMARK(BM_RecommendFromSweep)->Unit(benchmark::kMicrosecond);

void BM_DemoSourceFrame(benchmark::State& state) {
  nirslam::DemoOptions options;
  options.frame_count = 0;  // endless
  auto source = nirslam::make_demo_source(options);
  for (auto _ : state) benchmark::DoNotOptimize(source->next());
}
BENCHMARK(BM_DemoSourceFrame)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
