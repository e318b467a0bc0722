#pragma once

// Wall time of a stage, for the per-frame timings that snapshots and logs report.

#include <chrono>

namespace nirslam {

inline double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace nirslam
