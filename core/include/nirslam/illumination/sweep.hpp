#pragma once

// A power sweep of one scene: the frame metrics averaged per illuminator power. Frames are added
// one at a time (running means, Welford's update), so a sweep never holds images.

#include <span>
#include <string>
#include <vector>

#include "nirslam/illumination/saturation_curve.hpp"
#include "nirslam/quality/frame_metrics.hpp"

namespace nirslam {

// Mean and spread of a stream of values, updated one value at a time (Welford).
struct RunningStats {
  int count = 0;
  double mean = 0.0;
  double sum_squared_deviations = 0.0;

  void add(double value);
  // Sample standard deviation (n - 1); 0 with fewer than two values.
  double stddev() const;
};

struct SweepPoint {
  double power_w = 0.0;
  int frames = 0;
  RunningStats entropy_bits{};
  RunningStats saturated_fraction{};
  RunningStats black_fraction{};
  RunningStats mean{};             // grey, fraction of full scale
  RunningStats rms_contrast{};
  RunningStats gradient_energy{};
  RunningStats feature_count{};
  RunningStats coverage{};
  RunningStats evenness{};

  void add(const FrameMetrics& metrics);
};

class SweepRecord {
public:
  // Powers closer than this are one sweep point (an operator typing 50 and 50.0004 means one power).
  static constexpr double kSamePowerW = 1e-3;

  explicit SweepRecord(std::string scene = {}) : scene_(std::move(scene)) {}

  // Adds one frame taken at `power_w`. Throws std::invalid_argument for a negative or non-finite power.
  void add(double power_w, const FrameMetrics& metrics);
  // Adds a whole point (e.g. read back from a file); merged with an existing point of the same power.
  void add_point(const SweepPoint& point);

  const std::string& scene() const { return scene_; }
  const std::vector<SweepPoint>& points() const { return points_; }  // ascending power
  bool empty() const { return points_.empty(); }
  void clear() { points_.clear(); }
  const SweepPoint* find(double power_w) const;

  // The mean entropy per power, weighted by the frames averaged, for the curve fit.
  std::vector<CurveSample> entropy_samples() const;

private:
  SweepPoint& point_at(double power_w);

  std::string scene_;
  std::vector<SweepPoint> points_;
};

// The entropy samples of a list of points (mean per point, weight = frames).
std::vector<CurveSample> entropy_samples(std::span<const SweepPoint> points);

}  // namespace nirslam
