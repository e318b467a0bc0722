#pragma once

// The estimated inverse response against the truth inside the grey range the back end observed,
// after the best irradiance scale s: when the frames never saturate, the data fix G there only up
// to s (photometric_backend.hpp), so s G_est against G_true is what the calibration determined.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "nirslam/photometric/response_model.hpp"

namespace nirslam::test_photometric {

struct ResponseErrorModuloScale {
  double irradiance_scale = 1.0;  // least-squares s
  double mean_grey = 0.0;
  double max_grey = 0.0;
};

inline ResponseErrorModuloScale response_error_modulo_scale(const ResponseModel& estimate, const ResponseModel& truth,
                                                            double grey_low, double grey_high) {
  ResponseErrorModuloScale out;
  const std::vector<double> estimated = estimate.inverse_table(256);
  const std::vector<double> expected = truth.inverse_table(256);
  const int lo = std::clamp(static_cast<int>(std::ceil(grey_low)), 0, 255);
  const int hi = std::clamp(static_cast<int>(grey_high), 0, 255);
  if (hi < lo) return out;
  double num = 0.0, den = 0.0;
  for (int i = lo; i <= hi; ++i) {
    num += estimated[static_cast<std::size_t>(i)] * expected[static_cast<std::size_t>(i)];
    den += estimated[static_cast<std::size_t>(i)] * estimated[static_cast<std::size_t>(i)];
  }
  out.irradiance_scale = den > 0.0 ? num / den : 1.0;
  for (int i = lo; i <= hi; ++i) {
    const double d = std::abs(out.irradiance_scale * estimated[static_cast<std::size_t>(i)] - expected[static_cast<std::size_t>(i)]);
    out.mean_grey += d / (hi - lo + 1);
    out.max_grey = std::max(out.max_grey, d);
  }
  return out;
}

}  // namespace nirslam::test_photometric
