#pragma once

// The photometric residual of DSO between a host and a target frame, and its analytic
// Jacobians. A point is a host pixel x with inverse depth rho; its ray K^-1 x scaled by 1/rho,
// moved by T_target_host = (R, t), lands at q / rho with q = R K^-1 x + rho t, so the warp needs
// no division by rho and stays finite for points at infinity (rho = 0).
//
//   r = I_t(pi(q)) - s (I_h(x) - b_h) - b_t,     s = exp(a_t - a_h) e_t / e_h.
//
// Poses are T_cam_world, perturbed on the left (T <- exp(xi) T, xi = (upsilon, omega)); the
// derivative for the host pose follows from the one for T_target_host by the adjoint.

#include <array>
#include <cmath>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/odometry/image_pyramid.hpp"

namespace nirslam::odometry {

using Vector8d = Eigen::Matrix<double, 8, 1>;
using Matrix8d = Eigen::Matrix<double, 8, 8>;
using Matrix26d = Eigen::Matrix<double, 2, 6>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// DSO's 8-pixel residual pattern (its staticPattern[8]): a diamond around the point.
inline constexpr int kPatternSize = 8;
inline constexpr std::array<std::array<int, 2>, kPatternSize> kPattern{
    {{0, -2}, {-1, -1}, {1, -1}, {-2, 0}, {0, 0}, {2, 0}, {-1, 1}, {0, 2}}};

struct Warp {
  Eigen::Vector2d pixel;   // in the target
  double x = 0.0, y = 0.0;  // normalised target coordinates q_x / q_z, q_y / q_z
  double q_z = 1.0;
  double rho_target = 0.0;  // inverse depth in the target, rho / q_z
};

// Warps a host pixel; false when the point is behind the target camera.
inline bool warp_pixel(const LevelCamera& camera, const Eigen::Matrix3d& R_target_host,
                       const Eigen::Vector3d& t_target_host, const Eigen::Vector2d& host_pixel, double rho, Warp& w) {
  const Eigen::Vector3d q = R_target_host * camera.unproject(host_pixel) + rho * t_target_host;
  if (q.z() <= 1e-6) return false;
  w.q_z = q.z();
  w.x = q.x() / q.z();
  w.y = q.y() / q.z();
  w.rho_target = rho / q.z();
  w.pixel = {camera.fx * w.x + camera.cx, camera.fy * w.y + camera.cy};
  return true;
}

// d pixel / d xi of T_target_host (left perturbation) and d pixel / d rho.
inline void warp_jacobians(const LevelCamera& camera, const Warp& w, const Eigen::Vector3d& t_target_host,
                           Matrix26d& d_pixel_d_pose, Eigen::Vector2d& d_pixel_d_rho) {
  const double x = w.x;
  const double y = w.y;
  const double r = w.rho_target;
  d_pixel_d_pose << camera.fx * r, 0.0, -camera.fx * r * x, -camera.fx * x * y, camera.fx * (1.0 + x * x),
      -camera.fx * y,  //
      0.0, camera.fy * r, -camera.fy * r * y, -camera.fy * (1.0 + y * y), camera.fy * x * y, camera.fy * x;
  d_pixel_d_rho << camera.fx * (t_target_host.x() - x * t_target_host.z()) / w.q_z,
      camera.fy * (t_target_host.y() - y * t_target_host.z()) / w.q_z;
}

// Adjoint of T for xi = (upsilon, omega): exp(Ad_T xi) T = T exp(xi).
inline Matrix6d adjoint(const SE3& T) {
  Matrix6d ad = Matrix6d::Zero();
  const Eigen::Matrix3d R = T.rotation_matrix();
  ad.topLeftCorner<3, 3>() = R;
  ad.bottomRightCorner<3, 3>() = R;
  ad.topRightCorner<3, 3>() = skew(T.translation()) * R;
  return ad;
}

// Brightness transfer host -> target.
struct AffineTransfer {
  double scale = 1.0;  // exp(a_t - a_h) e_t / e_h
  double b_host = 0.0;
  double b_target = 0.0;
};
inline AffineTransfer affine_transfer(double a_host, double b_host, double exposure_host, double a_target,
                                      double b_target, double exposure_target) {
  return {std::exp(a_target - a_host) * exposure_target / exposure_host, b_host, b_target};
}

// Huber: IRLS weight and energy hw r^2 (2 - hw), which is r^2 inside and 2k|r| - k^2 outside.
inline double huber_weight(double r, double k) { return std::abs(r) < k ? 1.0 : k / std::abs(r); }

// One pattern pixel's residual and Jacobian, for tests and for clarity; the window optimiser
// inlines the same maths. Parameters per frame: (xi[6], a, b). Geometry of the Jacobian at
// `T_target_host_jacobian` (the first estimates), residual at `T_target_host`.
struct ResidualJacobian {
  double residual = 0.0;
  Vector8d d_host = Vector8d::Zero();
  Vector8d d_target = Vector8d::Zero();
  double d_rho = 0.0;
  Eigen::Vector3f target_sample = Eigen::Vector3f::Zero();  // (I, gx, gy) at the warped pixel
};
bool linearize_residual(const LevelCamera& camera, const PyramidLevel& target, const SE3& T_target_host,
                        const SE3& T_target_host_jacobian, const Eigen::Vector2d& host_pixel, double rho,
                        double host_intensity, const AffineTransfer& affine, ResidualJacobian& out);

}  // namespace nirslam::odometry
