#pragma once

// The photometric residual of DSO between a host and a target frame, and its analytic
// Jacobians. A point is a host pixel x with inverse depth rho; its ray K^-1 x scaled by 1/rho,
// moved by T_target_host = (R, t), lands at q / rho with q = R K^-1 x + rho t, so the warp needs
// no division by rho and stays finite for points at infinity (rho = 0).
//
//   r = I_t(pi(q)) - s g (I_h(x) - b_h) - b_t,     s = exp(a_t - a_h) e_t / e_h.
//
// g is the co-located illuminator's irradiance ratio (DESIGN.md, "The illuminator model"): the
// lamp at offset o from the camera centre lights the point with 1 / d^2, so g = d_h^2 / d_t^2
// with d = |X - o|, times the beam ratio when a beam is set (below); the power ratio P_t / P_h
// is a per-frame brightness factor like the exposure ratio and travels with it in e. With the
// correction off, g = 1.
//
// Poses are T_cam_world, perturbed on the left (T <- exp(xi) T, xi = (upsilon, omega)); the
// derivative for the host pose follows from the one for T_target_host by the adjoint.

#include <algorithm>
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

// The illuminator's factor g and its log-derivatives. The lamp at offset o in the camera frame
// lights a surface point X with B(alpha) cos(theta) / d^2: d = |X - o|, B(alpha) = cos(alpha)^m
// its beam (alpha off the optical axis; m = 0: no beam term, e.g. when the calibration's halo
// factor already holds it), theta between the surface normal n and the direction to the light.
//   g = (d_h / d_t)^2 * B(alpha_t) / B(alpha_h) * cos(theta_t) / cos(theta_h)
// In terms of the ray m = K^-1 x and q = R m + rho t (see above), u_h = m - rho o and
// u_t = q - rho o are the light-to-point vectors scaled by rho, so with n_h = |u_h|^2, n_t = |u_t|^2
//   log g = (1 + m/2 + c/2) (log n_h - log n_t) + m (log u_t,z - log u_h,z)
//           + c (log(-(R n) . u_t) - log(-n . u_h)),        c = 1 with a normal, else 0,
// finite at rho = 0 (where g = 1 without beam and normal). Under the left perturbation of
// T_target_host the target point moves by d_upsilon + d_omega x X_t, so
// d u_t = rho d_upsilon - [q]x d_omega and d (R n) = d_omega x R n; d u_h / d rho = -o,
// d u_t / d rho = t - o.
// Images whose grey values are irradiance^gamma (OdometryOptions::brightness_exponent) see the
// factor as g^gamma: log g and its derivatives are scaled by gamma.
struct LampGeometry {
  bool enabled = false;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // light position in the camera frame, odometry units
  double beam_exponent = 0.0;                        // m of B(alpha) = cos(alpha)^m
  double brightness_exponent = 1.0;                  // gamma of the images' encoding of irradiance
  // false: g from the current estimates, held in each linearisation (no derivatives), so
  // brightness errors of the photometric model cannot move poses and depths through it.
  bool derivatives = true;
  // With the beam carried here (frames corrected for the lens alone), a target's grey values are
  // B(alpha_t)^gamma times those of beam-corrected frames, so rim points weigh less than they
  // would there. true: residual and image gradient divided by it (target_beam_scale) before
  // the robust and gradient weights, so every point weighs as in beam-corrected frames.
  bool beam_corrected_weights = false;
};
struct LampFactor {
  double g = 1.0;
  Eigen::Matrix<double, 1, 6> d_log_g_d_pose = Eigen::Matrix<double, 1, 6>::Zero();  // of T_target_host
  double d_log_g_d_rho = 0.0;
};
// Below this cos(theta) in either view, the normal is not trusted (grazing light, or a wrong
// normal) and the cos term is left out.
inline constexpr double kMinLampCosine = 0.2;
// `normal_host`: the surface normal in the host camera frame (unit), or nullptr. False when the
// point sits on the light or, with a beam, behind it. `with_derivatives` false: g alone (the
// energy passes), also when lamp.derivatives is set.
// The three log terms share two logarithms: with s = n_h / n_t,
//   log g = m log(u_t,z / u_h,z sqrt(s)) + log(s [sqrt(s) c_t / c_h]),
// the bracket with a normal only. The window calls this twice per residual and pass and the
// epipolar search at every step; the logarithms are a small part of a call (README "Speed").
inline bool lamp_factor(const Eigen::Vector3d& ray, double rho, const Eigen::Matrix3d& R_target_host,
                        const Eigen::Vector3d& t_target_host, const LampGeometry& lamp, LampFactor& out,
                        const Eigen::Vector3d* normal_host = nullptr, bool with_derivatives = true) {
  const Eigen::Vector3d& o = lamp.offset;
  const double m = lamp.beam_exponent;
  const Eigen::Vector3d q = R_target_host * ray + rho * t_target_host;
  const Eigen::Vector3d u_h = ray - rho * o;
  const Eigen::Vector3d u_t = q - rho * o;
  const double n_h = u_h.squaredNorm();
  const double n_t = u_t.squaredNorm();
  if (n_h < 1e-12 || n_t < 1e-12) return false;
  const bool derivatives = with_derivatives && lamp.derivatives;
  const Eigen::Vector3d t_minus_o = t_target_host - o;
  const double norm_ratio = n_h / n_t;
  double norm_weight = 1.0;  // (1 + m/2 + c/2)
  double beam_argument = 1.0;   // u_t,z / u_h,z sqrt(s), raised to m
  double other_argument = norm_ratio;  // s, times sqrt(s) c_t / c_h with a normal
  double sqrt_norm_ratio = 0.0;  // 0: not taken yet
  Eigen::Vector3d w = Eigen::Vector3d::Zero();  // d log g / d u_t, but for the norm term
  Eigen::Vector3d d_rot_extra = Eigen::Vector3d::Zero();
  double d_rho_extra = 0.0;
  if (m != 0.0) {
    if (u_h.z() < 1e-9 || u_t.z() < 1e-9) return false;
    norm_weight += 0.5 * m;
    sqrt_norm_ratio = std::sqrt(norm_ratio);
    beam_argument = u_t.z() / u_h.z() * sqrt_norm_ratio;
    if (derivatives) {
      w.z() += m / u_t.z();
      d_rho_extra += m * (t_minus_o.z() / u_t.z() + o.z() / u_h.z());
    }
  }
  if (normal_host != nullptr) {
    const Eigen::Vector3d Rn = R_target_host * *normal_host;
    const double c_h = -normal_host->dot(u_h);  // |u_h| cos(theta_h)
    const double c_t = -Rn.dot(u_t);
    constexpr double kMinCosineSquared = kMinLampCosine * kMinLampCosine;
    if (c_h > 0.0 && c_t > 0.0 && c_h * c_h > kMinCosineSquared * n_h && c_t * c_t > kMinCosineSquared * n_t) {
      norm_weight += 0.5;
      if (sqrt_norm_ratio == 0.0) sqrt_norm_ratio = std::sqrt(norm_ratio);
      other_argument *= sqrt_norm_ratio * c_t / c_h;
      if (derivatives) {
        // Rn . u_t = -c_t, n . u_h = -c_h.
        const double inv_c_t = 1.0 / c_t;
        w -= inv_c_t * Rn;
        d_rot_extra = -inv_c_t * Rn.cross(u_t);
        d_rho_extra -= Rn.dot(t_minus_o) * inv_c_t + normal_host->dot(o) / c_h;
      }
    }
  }
  double log_g = std::log(other_argument);
  if (m != 0.0) log_g += m * std::log(beam_argument);
  const double gamma = lamp.brightness_exponent;
  out.g = std::exp(gamma * log_g);
  if (!derivatives) {
    out.d_log_g_d_pose.setZero();
    out.d_log_g_d_rho = 0.0;
    return true;
  }
  w += (-2.0 * norm_weight / n_t) * u_t;
  out.d_log_g_d_pose.head<3>() = gamma * rho * w.transpose();
  out.d_log_g_d_pose.tail<3>() = gamma * (q.cross(w) + d_rot_extra).transpose();
  out.d_log_g_d_rho = gamma * (norm_weight * (-2.0 * u_h.dot(o) / n_h - 2.0 * u_t.dot(t_minus_o) / n_t) + d_rho_extra);
  return true;
}
// Value only (the energy passes); 1 where lamp_factor fails.
inline double lamp_factor_value(const Eigen::Vector3d& ray, double rho, const Eigen::Matrix3d& R_target_host,
                                const Eigen::Vector3d& t_target_host, const LampGeometry& lamp,
                                const Eigen::Vector3d* normal_host = nullptr) {
  LampFactor f;
  return lamp_factor(ray, rho, R_target_host, t_target_host, lamp, f, normal_host, false) ? f.g : 1.0;
}

// B(alpha_t)^gamma of the target's view of a point (1 unless lamp.beam_corrected_weights with a
// beam), held as a weight, not differentiated, as DSO holds its gradient weights. Floored so a
// point near the beam's edge cannot dominate.
inline constexpr double kMinTargetBeamScale = 0.05;
inline double target_beam_scale(const Eigen::Vector3d& ray, double rho, const Eigen::Matrix3d& R_target_host,
                                const Eigen::Vector3d& t_target_host, const LampGeometry& lamp) {
  if (!lamp.enabled || !lamp.beam_corrected_weights || lamp.beam_exponent == 0.0) return 1.0;
  const Eigen::Vector3d u_t = R_target_host * ray + rho * (t_target_host - lamp.offset);
  const double n_t = u_t.norm();
  if (n_t < 1e-12 || u_t.z() <= 0.0) return 1.0;
  return std::max(kMinTargetBeamScale, std::pow(u_t.z() / n_t, lamp.beam_exponent * lamp.brightness_exponent));
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
                        double host_intensity, const AffineTransfer& affine, ResidualJacobian& out,
                        const LampGeometry& lamp = {}, const Eigen::Vector3d* normal_host = nullptr);

}  // namespace nirslam::odometry
