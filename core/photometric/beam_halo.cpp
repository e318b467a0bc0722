#include "nirslam/photometric/beam_halo.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include <Eigen/Dense>

namespace nirslam {

BeamHalo::BeamHalo(VignetteModel lens, const std::vector<double>& radii, const std::vector<double>& cos_alpha,
                   double initial_exponent)
    : lens_(std::move(lens)), initial_exponent_(initial_exponent) {
  const auto n = static_cast<Eigen::Index>(radii.size());
  if (n < 4 || radii.size() != cos_alpha.size())
    throw std::invalid_argument("beam halo: at least 4 radii, each with its cos(alpha)");
  Eigen::MatrixXd basis(n, 3);
  lens_samples_.resize(n);
  log_cos_.resize(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    const double r = radii[static_cast<std::size_t>(j)], c = cos_alpha[static_cast<std::size_t>(j)];
    if (!(c > 0.0 && c <= 1.0)) throw std::invalid_argument("beam halo: cos(alpha) outside (0, 1]");
    const double t = r * r;
    basis.row(j) << t, t * t, t * t * t;
    lens_samples_[j] = lens_(r);
    log_cos_[j] = std::log(c);
    if (!(r > 0.0) || (j > 0 && !(r > radii_.back()))) throw std::invalid_argument("beam halo: radii must be positive and increase");
    radii_.push_back(r);
  }
  // P = (A^T A)^-1 A^T, once: every v(m) is then a product.
  projection_ = (basis.transpose() * basis).ldlt().solve(basis.transpose());
}

Eigen::Vector3d BeamHalo::vignette(double beam_exponent, Eigen::Vector3d* dv_dm) const {
  const Eigen::VectorXd halo = lens_samples_.array() * (beam_exponent * log_cos_.array()).exp();
  if (dv_dm != nullptr) *dv_dm = projection_ * (halo.array() * log_cos_.array()).matrix();
  return projection_ * (halo.array() - 1.0).matrix();
}

double BeamHalo::log_cos(double r) const {
  // Segment [r0, r1] holding r: from (0, 0) to the first radius, then between given radii.
  const auto upper = std::upper_bound(radii_.begin(), radii_.end(), r);
  std::size_t i1 = static_cast<std::size_t>(upper - radii_.begin());
  if (i1 >= radii_.size()) i1 = radii_.size() - 1;
  const double r1 = radii_[i1], y1 = log_cos_[static_cast<Eigen::Index>(i1)];
  const double r0 = i1 == 0 ? 0.0 : radii_[i1 - 1];
  const double y0 = i1 == 0 ? 0.0 : log_cos_[static_cast<Eigen::Index>(i1 - 1)];
  return y0 + (y1 - y0) * (r - r0) / (r1 - r0);
}

BeamHalo beam_halo_for_camera(const CameraModel& camera, const VignetteModel& lens, double initial_exponent) {
  constexpr int kRadii = 64;
  const Eigen::Vector2d centre(0.5 * (camera.width() - 1), 0.5 * (camera.height() - 1));
  std::vector<double> radii, cos_alpha;
  for (int i = 0; i < kRadii; ++i) {
    const double r = (i + 0.5) / kRadii;
    const auto ray = camera.unproject(centre + r * centre);
    if (!ray || !(ray->normalized().z() > 0.0)) continue;
    radii.push_back(r);
    cos_alpha.push_back(std::min(ray->normalized().z(), 1.0));
  }
  return BeamHalo(lens, radii, cos_alpha, initial_exponent);
}

}  // namespace nirslam
