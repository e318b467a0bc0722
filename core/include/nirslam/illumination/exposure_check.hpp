#pragma once

// The live verdict on one frame that the operator sees as a banner: clipped (too many saturated
// pixels: lower the power), too dark (raise it), or fine.

#include <string>

#include "nirslam/quality/image_quality.hpp"

namespace nirslam {

struct ExposureLimits {
  double max_saturated_fraction = 0.01;  // more saturated pixels than this: clipped
  double dark_mean = 0.10;               // mean grey below this fraction of full scale: too dark
  double dark_black_fraction = 0.30;     // or more pixels than this at code 0: too dark
};

enum class ExposureVerdict { Unknown, Ok, Clipped, Dark, ClippedAndDark };
const char* to_string(ExposureVerdict verdict);

struct ExposureCheck {
  ExposureVerdict verdict = ExposureVerdict::Unknown;
  std::string message;  // one line for the banner, with the numbers; empty when Unknown

  bool clipped() const { return verdict == ExposureVerdict::Clipped || verdict == ExposureVerdict::ClippedAndDark; }
  bool dark() const { return verdict == ExposureVerdict::Dark || verdict == ExposureVerdict::ClippedAndDark; }
};

ExposureCheck check_exposure(const ImageQuality& quality, const ExposureLimits& limits);

}  // namespace nirslam
