#pragma once

// The Huber loss of a residual r with threshold delta, as the photometric and illumination
// estimators use it in iteratively reweighted least squares.

#include <cmath>

namespace nirslam {

// IRLS weight: 1 inside the threshold, delta/|r| outside.
inline double huber_weight(double r, double delta) {
  const double a = std::abs(r);
  return a <= delta ? 1.0 : delta / a;
}

// Twice the Huber loss, so that it equals the squared residual r^2 inside the threshold
// (2 delta |r| - delta^2 outside): the cost a least-squares fit of squared residuals sums.
inline double twice_huber_loss(double r, double delta) {
  const double a = std::abs(r);
  return a <= delta ? r * r : 2.0 * delta * a - delta * delta;
}

// The Huber loss itself: r^2/2 inside the threshold, delta (|r| - delta/2) outside.
inline double huber_loss(double r, double delta) {
  const double a = std::abs(r);
  return a <= delta ? 0.5 * r * r : delta * (a - 0.5 * delta);
}

}  // namespace nirslam
