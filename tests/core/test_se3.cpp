#include <gtest/gtest.h>

#include "nirslam/geometry/se3.hpp"

namespace nirslam {
namespace {

TEST(SO3, ExpLogRoundTripIncludingSmallAndLargeAngles) {
  for (const Eigen::Vector3d& omega : {Eigen::Vector3d(1e-9, -2e-9, 0.5e-9), Eigen::Vector3d(0.1, -0.2, 0.3),
                                      Eigen::Vector3d(0.0, 3.0, 0.0), Eigen::Vector3d(-1.0, 1.0, 2.0)}) {
    const Eigen::Matrix3d R = so3_exp(omega);
    EXPECT_NEAR((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_NEAR((so3_log(R) - omega).norm(), 0.0, 1e-9) << omega.transpose();
  }
}

TEST(SE3, ExpLogRoundTripAndGroupLaws) {
  Vector6d xi_a, xi_b;
  xi_a << 0.3, -0.1, 2.0, 0.2, -0.4, 0.9;
  xi_b << -1.0, 0.5, 0.1, -0.7, 0.05, 0.3;
  const SE3 a = SE3::exp(xi_a), b = SE3::exp(xi_b);
  EXPECT_NEAR((a.log() - xi_a).norm(), 0.0, 1e-10);
  EXPECT_NEAR(((a * a.inverse()).matrix() - Eigen::Matrix4d::Identity()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(((a * b).matrix() - a.matrix() * b.matrix()).norm(), 0.0, 1e-12);
  const Eigen::Vector3d p(0.4, -2.0, 7.0);
  EXPECT_NEAR(((a * b) * p - a * (b * p)).norm(), 0.0, 1e-12);
  // Pure translation: exp gives the translation back unchanged.
  Vector6d xi_t = Vector6d::Zero();
  xi_t.head<3>() << 1.0, 2.0, 3.0;
  EXPECT_NEAR((SE3::exp(xi_t).translation() - Eigen::Vector3d(1, 2, 3)).norm(), 0.0, 1e-15);
}

TEST(SE3, LookAtPointsTheOpticalAxisAtTheTarget) {
  const Eigen::Vector3d eye(1, 2, 3), target(4, 2, 3), down(0, 0, -1);
  const SE3 T_world_cam = look_at(eye, target, down);
  const Eigen::Vector3d target_in_cam = T_world_cam.inverse() * target;
  EXPECT_NEAR(target_in_cam.x(), 0.0, 1e-12);
  EXPECT_NEAR(target_in_cam.y(), 0.0, 1e-12);
  EXPECT_NEAR(target_in_cam.z(), 3.0, 1e-12);
  // Image y points down in the world.
  EXPECT_NEAR((T_world_cam.rotation_matrix().col(1) - down).norm(), 0.0, 1e-12);
  EXPECT_THROW(look_at(eye, eye, down), std::invalid_argument);
}

}  // namespace
}  // namespace nirslam
