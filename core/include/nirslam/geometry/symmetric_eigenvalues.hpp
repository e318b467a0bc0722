#pragma once

// Eigenvalues of a symmetric 2x2 matrix in closed form. Eigen's SelfAdjointEigenSolver<Matrix2d>
// gives the same, but instantiating it cost 10 s of compile per translation unit (16 s under the
// sanitizers, 2026-12-07), where the callers only gate on a scatter's spread.

#include <cmath>

#include <Eigen/Core>

namespace nirslam {

// Ascending, as SelfAdjointEigenSolver returns them; reads the lower triangle as it does.
inline Eigen::Vector2d symmetric_eigenvalues(const Eigen::Matrix2d& m) {
  const double half_trace = 0.5 * (m(0, 0) + m(1, 1));
  const double half_difference = 0.5 * (m(0, 0) - m(1, 1));
  const double radius = std::hypot(half_difference, m(1, 0));
  return {half_trace - radius, half_trace + radius};
}

}  // namespace nirslam
