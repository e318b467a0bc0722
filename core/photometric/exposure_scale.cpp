#include "nirslam/photometric/exposure_scale.hpp"

#include <cmath>

namespace nirslam {

void ReportedExposureScaleTracker::add(const ExposureSample& s) {
  if (s.status != ExposureStatus::Estimated || !s.estimated || !s.reported) return;
  if (!(*s.estimated > 0.0) || !(*s.reported > 0.0) || !std::isfinite(*s.estimated) || !std::isfinite(*s.reported))
    return;
  const double log_ratio = std::log(*s.reported / *s.estimated);
  if (lower_.empty() || log_ratio <= lower_.top())
    lower_.push(log_ratio);
  else
    upper_.push(log_ratio);
  // Keep |lower| = |upper| or |upper| + 1.
  if (lower_.size() > upper_.size() + 1) {
    upper_.push(lower_.top());
    lower_.pop();
  } else if (upper_.size() > lower_.size()) {
    lower_.push(upper_.top());
    upper_.pop();
  }
}

ReportedExposureScale ReportedExposureScaleTracker::current() const {
  ReportedExposureScale scale;
  scale.frames = static_cast<int>(lower_.size() + upper_.size());
  if (scale.frames == 0) return scale;
  // Even count: the mean of the two middle values.
  const double log_median = lower_.size() > upper_.size() ? lower_.top() : 0.5 * (lower_.top() + upper_.top());
  scale.factor = std::exp(log_median);
  return scale;
}

void ReportedExposureScaleTracker::reset() {
  lower_ = {};
  upper_ = {};
}

ReportedExposureScale reported_exposure_scale(const std::vector<ExposureSample>& history) {
  ReportedExposureScaleTracker tracker;
  for (const ExposureSample& s : history) tracker.add(s);
  return tracker.current();
}

}  // namespace nirslam
