#pragma once

// Rigid motions as small value types (the parts of Sophus that nirslam needs; Debian ships no Lie
// group library). Naming follows the frames: T_world_cam maps points from camera to world
// coordinates, and T_a_b * T_b_c = T_a_c.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace nirslam {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Rotation matrix from a rotation vector (axis * angle), exact near zero.
Eigen::Matrix3d so3_exp(const Eigen::Vector3d& omega);
// Rotation vector of a rotation matrix, angle in [0, pi].
Eigen::Vector3d so3_log(const Eigen::Matrix3d& R);
// [v]x: the matrix of the cross product v x (.)
Eigen::Matrix3d skew(const Eigen::Vector3d& v);

class SE3 {
public:
  SE3() = default;
  SE3(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
      : rotation_(rotation.normalized()), translation_(translation) {}
  SE3(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation)
      : rotation_(Eigen::Quaterniond(rotation).normalized()), translation_(translation) {}

  static SE3 identity() { return {}; }
  // Tangent vector ordered (translation part upsilon, rotation part omega), as in Sophus.
  static SE3 exp(const Vector6d& xi);
  Vector6d log() const;

  const Eigen::Quaterniond& unit_quaternion() const { return rotation_; }
  Eigen::Matrix3d rotation_matrix() const { return rotation_.toRotationMatrix(); }
  const Eigen::Vector3d& translation() const { return translation_; }
  Eigen::Matrix4d matrix() const;

  SE3 inverse() const;
  SE3 operator*(const SE3& other) const {
    return {rotation_ * other.rotation_, rotation_ * other.translation_ + translation_};
  }
  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const { return rotation_ * point + translation_; }

private:
  Eigen::Quaterniond rotation_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation_ = Eigen::Vector3d::Zero();
};

// Camera pose that looks from `eye` towards `target`, image y axis pointing as close to `down` as
// possible (camera frame: x right, y down, z forward).
SE3 look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& down);

}  // namespace nirslam
