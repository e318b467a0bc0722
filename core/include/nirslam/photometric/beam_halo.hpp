#pragma once

// The halo factor as the lens vignette times the lamp's beam, with the beam's exponent as its
// only unknown (issue 8: the halo factor H = V B "with an option to separate them when the lens
// vignetting is known from an earlier calibration"). With the lamp beside the lens, B is the
// beam at the pixel's angle alpha off the optical axis, B = cos(alpha)^m, so
//
//   H(r) = V_lens(r) cos(alpha(r))^m,
//
// which the back end's radial polynomial holds as v(m): the least-squares fit of
// 1 + v1 r^2 + v2 r^4 + v3 r^6 to H at radii along the image diagonal (as Simulator::
// halo_factor() does). That fit is linear in the samples, v(m) = P (h(m) - 1), so
// dv/dm = P (h(m) log cos(alpha)) exactly. Three free coefficients under the lamp are what the
// co-lit calibration gets wrong for the odometry (README "Illuminator correction": the true lens
// vignette times the true beam, held, halves the lamp mode's error against the halo estimated
// freely); one exponent is what a lamp's data sheet states.

#include <vector>

#include <Eigen/Core>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

class BeamHalo {
public:
  // `radii` in (0, 1] (VignetteModel's normalised radius) with cos(alpha) of the ray there.
  // Throws std::invalid_argument for fewer than 4 radii, sizes that differ or a cosine outside (0, 1].
  BeamHalo(VignetteModel lens, const std::vector<double>& radii, const std::vector<double>& cos_alpha,
           double initial_exponent);

  // v of the polynomial closest to V_lens cos(alpha)^m; with dv_dm, its derivative in m.
  Eigen::Vector3d vignette(double beam_exponent, Eigen::Vector3d* dv_dm = nullptr) const;
  // log cos(alpha) at radius r, linear between the radii given (0 at r = 0, the last interval
  // continued beyond them).
  double log_cos(double r) const;
  const VignetteModel& lens() const { return lens_; }
  double initial_exponent() const { return initial_exponent_; }

private:
  VignetteModel lens_;
  double initial_exponent_ = 0.0;
  Eigen::Matrix<double, 3, Eigen::Dynamic> projection_;  // P: samples minus 1 -> v
  Eigen::VectorXd lens_samples_, log_cos_;
  std::vector<double> radii_;  // ascending, with log_cos_ (the constructor's order)
};

// Radii along the diagonal of `camera`'s image (centre + r (corner - centre), 64 of them) and
// their angles off the axis from its unprojection.
BeamHalo beam_halo_for_camera(const CameraModel& camera, const VignetteModel& lens, double initial_exponent);

}  // namespace nirslam
