#include "nirslam/geometry/se3.hpp"

#include <cmath>
#include <stdexcept>

namespace nirslam {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& omega) {
  const double theta_sq = omega.squaredNorm();
  const Eigen::Matrix3d W = skew(omega);
  if (theta_sq < 1e-10) return Eigen::Matrix3d::Identity() + W + 0.5 * W * W;  // Taylor
  const double theta = std::sqrt(theta_sq);
  return Eigen::Matrix3d::Identity() + std::sin(theta) / theta * W +
         (1.0 - std::cos(theta)) / theta_sq * W * W;
}

Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd angle_axis(R);
  return angle_axis.angle() * angle_axis.axis();
}

namespace {

// Left Jacobian of SO(3), V in the SE(3) exponential: t = V * upsilon.
Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& omega) {
  const double theta_sq = omega.squaredNorm();
  const Eigen::Matrix3d W = skew(omega);
  if (theta_sq < 1e-10) return Eigen::Matrix3d::Identity() + 0.5 * W + W * W / 6.0;
  const double theta = std::sqrt(theta_sq);
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / theta_sq * W +
         (theta - std::sin(theta)) / (theta_sq * theta) * W * W;
}

}  // namespace

SE3 SE3::exp(const Vector6d& xi) {
  const Eigen::Vector3d upsilon = xi.head<3>();
  const Eigen::Vector3d omega = xi.tail<3>();
  return SE3(Eigen::Matrix3d(so3_exp(omega)), Eigen::Vector3d(so3_left_jacobian(omega) * upsilon));
}

Vector6d SE3::log() const {
  const Eigen::Vector3d omega = so3_log(rotation_matrix());
  Vector6d xi;
  xi.head<3>() = so3_left_jacobian(omega).inverse() * translation_;
  xi.tail<3>() = omega;
  return xi;
}

Eigen::Matrix4d SE3::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = rotation_matrix();
  m.topRightCorner<3, 1>() = translation_;
  return m;
}

SE3 SE3::inverse() const {
  const Eigen::Quaterniond inverse_rotation = rotation_.conjugate();
  return {inverse_rotation, -(inverse_rotation * translation_)};
}

SE3 look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& down) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = down.cross(z);
  if (!z.allFinite() || x.norm() < 1e-9)
    throw std::invalid_argument("look_at: eye equals target, or viewing direction parallel to 'down'");
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R_world_cam;
  R_world_cam.col(0) = x;
  R_world_cam.col(1) = y;
  R_world_cam.col(2) = z;
  return SE3(R_world_cam, eye);
}

}  // namespace nirslam
