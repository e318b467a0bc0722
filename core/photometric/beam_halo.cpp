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
  }
  // P = (A^T A)^-1 A^T, once: every v(m) is then a product.
  projection_ = (basis.transpose() * basis).ldlt().solve(basis.transpose());
}

Eigen::Vector3d BeamHalo::vignette(double beam_exponent, Eigen::Vector3d* dv_dm) const {
  const Eigen::VectorXd halo = lens_samples_.array() * (beam_exponent * log_cos_.array()).exp();
  if (dv_dm != nullptr) *dv_dm = projection_ * (halo.array() * log_cos_.array()).matrix();
  return projection_ * (halo.array() - 1.0).matrix();
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
