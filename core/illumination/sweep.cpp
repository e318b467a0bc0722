#include "nirslam/illumination/sweep.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace nirslam {

void RunningStats::add(double value) {
  ++count;
  const double delta = value - mean;
  mean += delta / count;
  sum_squared_deviations += delta * (value - mean);
}

double RunningStats::stddev() const {
  return count > 1 ? std::sqrt(std::max(0.0, sum_squared_deviations / (count - 1))) : 0.0;
}

namespace {

// Chan et al.'s pairwise update: the statistics of two streams as one.
void merge(RunningStats& into, const RunningStats& other) {
  if (other.count == 0) return;
  if (into.count == 0) {
    into = other;
    return;
  }
  const int n = into.count + other.count;
  const double delta = other.mean - into.mean;
  into.sum_squared_deviations +=
      other.sum_squared_deviations + delta * delta * static_cast<double>(into.count) * other.count / n;
  into.mean += delta * other.count / n;
  into.count = n;
}

}  // namespace

void SweepPoint::add(const FrameMetrics& m) {
  ++frames;
  entropy_bits.add(m.quality.entropy_bits);
  saturated_fraction.add(m.quality.saturated_fraction);
  black_fraction.add(m.quality.black_fraction);
  mean.add(m.quality.mean);
  rms_contrast.add(m.quality.rms_contrast);
  gradient_energy.add(m.structure.gradient_energy);
  feature_count.add(m.structure.feature_count);
  coverage.add(m.structure.coverage);
  evenness.add(m.structure.evenness);
}

SweepPoint& SweepRecord::point_at(double power_w) {
  if (!std::isfinite(power_w) || power_w < 0.0)
    throw std::invalid_argument("sweep: illuminator power must be a finite number >= 0 W, got " +
                                std::to_string(power_w));
  const auto it = std::lower_bound(points_.begin(), points_.end(), power_w - kSamePowerW,
                                   [](const SweepPoint& p, double w) { return p.power_w < w; });
  if (it != points_.end() && std::abs(it->power_w - power_w) <= kSamePowerW) return *it;
  SweepPoint point;
  point.power_w = power_w;
  return *points_.insert(it, point);
}

void SweepRecord::add(double power_w, const FrameMetrics& metrics) { point_at(power_w).add(metrics); }

void SweepRecord::add_point(const SweepPoint& point) {
  SweepPoint& into = point_at(point.power_w);
  into.frames += point.frames;
  merge(into.entropy_bits, point.entropy_bits);
  merge(into.saturated_fraction, point.saturated_fraction);
  merge(into.black_fraction, point.black_fraction);
  merge(into.mean, point.mean);
  merge(into.rms_contrast, point.rms_contrast);
  merge(into.gradient_energy, point.gradient_energy);
  merge(into.feature_count, point.feature_count);
  merge(into.coverage, point.coverage);
  merge(into.evenness, point.evenness);
}

const SweepPoint* SweepRecord::find(double power_w) const {
  for (const SweepPoint& p : points_)
    if (std::abs(p.power_w - power_w) <= kSamePowerW) return &p;
  return nullptr;
}

std::vector<CurveSample> SweepRecord::entropy_samples() const { return nirslam::entropy_samples(points_); }

std::vector<CurveSample> entropy_samples(std::span<const SweepPoint> points) {
  std::vector<CurveSample> samples;
  samples.reserve(points.size());
  for (const SweepPoint& p : points)
    if (p.frames > 0) samples.push_back({p.power_w, p.entropy_bits.mean, static_cast<double>(p.frames)});
  return samples;
}

}  // namespace nirslam
