#include "nirslam/illumination/exposure_check.hpp"

#include <spdlog/fmt/fmt.h>

namespace nirslam {

const char* to_string(ExposureVerdict verdict) {
  switch (verdict) {
    case ExposureVerdict::Unknown: return "unknown";
    case ExposureVerdict::Ok: return "ok";
    case ExposureVerdict::Clipped: return "clipped";
    case ExposureVerdict::Dark: return "dark";
    case ExposureVerdict::ClippedAndDark: return "clipped and dark";
  }
  return "unknown";
}

ExposureCheck check_exposure(const ImageQuality& q, const ExposureLimits& limits) {
  const bool clipped = q.saturated_fraction > limits.max_saturated_fraction;
  const bool dark = q.mean < limits.dark_mean || q.black_fraction > limits.dark_black_fraction;
  ExposureCheck check;
  // Short enough for the banner; the numbers first, the advice last.
  const std::string saturation = fmt::format("{:.1f} % saturated (limit {:.1f} %)", 100.0 * q.saturated_fraction,
                                             100.0 * limits.max_saturated_fraction);
  const std::string darkness = fmt::format("mean grey {:.0f} %, {:.0f} % black", 100.0 * q.mean, 100.0 * q.black_fraction);
  if (clipped && dark) {
    check.verdict = ExposureVerdict::ClippedAndDark;
    check.message = fmt::format("Clipped and dark: {}, {}: the scene exceeds the sensor's range", saturation, darkness);
  } else if (clipped) {
    check.verdict = ExposureVerdict::Clipped;
    check.message = fmt::format("Clipped: {}: lower the power", saturation);
  } else if (dark) {
    check.verdict = ExposureVerdict::Dark;
    check.message = fmt::format("Too dark: {}: raise the power", darkness);
  } else {
    check.verdict = ExposureVerdict::Ok;
    check.message = fmt::format("Exposure OK: mean grey {:.0f} %, {:.2f} % saturated", 100.0 * q.mean,
                                100.0 * q.saturated_fraction);
  }
  return check;
}

}  // namespace nirslam
