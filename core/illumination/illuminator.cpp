#include "nirslam/illumination/illuminator.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <spdlog/fmt/fmt.h>

namespace nirslam {

double IlluminatorCapabilities::settable(double watts) const {
  if (!std::isfinite(watts) || watts < min_power_w - 1e-9 || watts > max_power_w + 1e-9)
    throw std::out_of_range(fmt::format("illuminator power {:g} W outside the range {:g}..{:g} W of {}", watts,
                                        min_power_w, max_power_w, description));
  if (step_w <= 0.0) return watts;
  const double stepped = min_power_w + std::round((watts - min_power_w) / step_w) * step_w;
  return std::min(stepped, max_power_w);
}

double ManualIlluminator::set_power(double watts) {
  power_w_ = capabilities_.settable(watts);
  return *power_w_;
}

}  // namespace nirslam
