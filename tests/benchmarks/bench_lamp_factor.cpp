// The co-located lamp's factor per residual: `build/nirslam_benchmarks --benchmark_filter=LampFactor`.
// The window's linearisation takes it twice per residual (with derivatives at the first
// estimates, value only at the current state) and the epipolar search at every step: about 5 %
// of all CPU with all modes on. Arguments: with derivatives (1) or value only (0).
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "nirslam/odometry/photometric_residual.hpp"

namespace {

using nirslam::odometry::LampFactor;
using nirslam::odometry::LampGeometry;

void BM_LampFactor(benchmark::State& state) {
  const bool derivatives = state.range(0) != 0;
  // A beam (m = 4.8, the simulator's 30 degrees), a 5 cm offset in units of a 2 m deep scene and
  // a surface normal: the illuminated mode's most expensive case.
  LampGeometry lamp;
  lamp.enabled = true;
  lamp.offset = Eigen::Vector3d(0.025, 0.0, 0.0);
  lamp.beam_exponent = 4.8;
  lamp.brightness_exponent = 0.5;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.05, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.08, -0.02, -0.15);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> xy(-0.5, 0.5), rho(0.3, 1.2);
  constexpr int kPoints = 1024;
  std::vector<Eigen::Vector3d> rays, normals;
  std::vector<double> inverse_depths;
  for (int i = 0; i < kPoints; ++i) {
    rays.emplace_back(xy(rng), xy(rng), 1.0);
    normals.push_back(Eigen::Vector3d(0.1 * xy(rng), 0.1 * xy(rng), -1.0).normalized());
    inverse_depths.push_back(rho(rng));
  }
  double sum = 0.0;
  for (auto _ : state) {
    for (int i = 0; i < kPoints; ++i) {
      LampFactor f;
      const auto k = static_cast<std::size_t>(i);
      if (nirslam::odometry::lamp_factor(rays[k], inverse_depths[k], R, t, lamp, f, &normals[k], derivatives))
        sum += f.g + f.d_log_g_d_rho;
    }
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_LampFactor)->Arg(1)->Arg(0);

}  // namespace
