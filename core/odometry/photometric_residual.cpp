#include "nirslam/odometry/photometric_residual.hpp"

namespace nirslam::odometry {

bool linearize_residual(const LevelCamera& camera, const PyramidLevel& target, const SE3& T_target_host,
                        const SE3& T_target_host_jacobian, const Eigen::Vector2d& host_pixel, double rho,
                        double host_intensity, const AffineTransfer& affine, ResidualJacobian& out,
                        const LampGeometry& lamp, const Eigen::Vector3d* normal_host) {
  Warp w;
  if (!warp_pixel(camera, T_target_host.rotation_matrix(), T_target_host.translation(), host_pixel, rho, w)) return false;
  if (!camera.inside(w.pixel.x(), w.pixel.y(), 1.0)) return false;
  const Eigen::Vector3f sample =
      target.interpolate(static_cast<float>(w.pixel.x()), static_cast<float>(w.pixel.y()));
  out.target_sample = sample;
  const Eigen::Vector3d ray = camera.unproject(host_pixel);
  const double g =
      lamp.enabled ? lamp_factor_value(ray, rho, T_target_host.rotation_matrix(), T_target_host.translation(), lamp,
                                       normal_host)
                   : 1.0;
  out.residual = sample[0] - g * affine.scale * (host_intensity - affine.b_host) - affine.b_target;

  Warp w_lin;
  if (!warp_pixel(camera, T_target_host_jacobian.rotation_matrix(), T_target_host_jacobian.translation(), host_pixel,
                  rho, w_lin))
    return false;
  Matrix26d d_pixel_d_pose;
  Eigen::Vector2d d_pixel_d_rho;
  warp_jacobians(camera, w_lin, T_target_host_jacobian.translation(), d_pixel_d_pose, d_pixel_d_rho);
  const Eigen::Vector2d gradient = sample.tail<2>().cast<double>();
  Eigen::Matrix<double, 1, 6> d_rel = gradient.transpose() * d_pixel_d_pose;
  const double host_term = g * affine.scale * (host_intensity - affine.b_host);
  out.d_rho = gradient.dot(d_pixel_d_rho);
  if (lamp.enabled) {
    // r depends on g through -host_term: d r = -host_term d log g.
    LampFactor df;
    if (!lamp_factor(ray, rho, T_target_host_jacobian.rotation_matrix(), T_target_host_jacobian.translation(), lamp,
                     df, normal_host))
      return false;
    d_rel -= host_term * df.d_log_g_d_pose;
    out.d_rho -= host_term * df.d_log_g_d_rho;
  }
  out.d_target.head<6>() = d_rel.transpose();
  out.d_host.head<6>() = -(d_rel * adjoint(T_target_host_jacobian)).transpose();
  out.d_target[6] = -host_term;
  out.d_target[7] = -1.0;
  out.d_host[6] = host_term;
  out.d_host[7] = g * affine.scale;
  return true;
}

}  // namespace nirslam::odometry
