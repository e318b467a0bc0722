#include "nirslam/photometric/exposure_scale.hpp"

#include <algorithm>
#include <cmath>

namespace nirslam {

ReportedExposureScale reported_exposure_scale(const std::vector<ExposureSample>& history) {
  std::vector<double> log_ratios;
  for (const ExposureSample& s : history) {
    if (s.status != ExposureStatus::Estimated || !s.estimated || !s.reported) continue;
    if (!(*s.estimated > 0.0) || !(*s.reported > 0.0) || !std::isfinite(*s.estimated) || !std::isfinite(*s.reported))
      continue;
    log_ratios.push_back(std::log(*s.reported / *s.estimated));
  }
  ReportedExposureScale scale;
  scale.frames = static_cast<int>(log_ratios.size());
  if (log_ratios.empty()) return scale;
  const auto middle = log_ratios.begin() + static_cast<std::ptrdiff_t>(log_ratios.size() / 2);
  std::nth_element(log_ratios.begin(), middle, log_ratios.end());
  double log_median = *middle;
  if (log_ratios.size() % 2 == 0) {  // the mean of the two middle values: symmetric in the order
    log_median = 0.5 * (log_median + *std::max_element(log_ratios.begin(), middle));
  }
  scale.factor = std::exp(log_median);
  return scale;
}

std::vector<ExposureSample> on_reported_scale(const std::vector<ExposureSample>& history) {
  const double factor = reported_exposure_scale(history).factor;
  std::vector<ExposureSample> scaled = history;
  for (ExposureSample& s : scaled)
    if (s.estimated) *s.estimated *= factor;
  return scaled;
}

}  // namespace nirslam
