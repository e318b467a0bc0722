// The analytic Jacobians of the photometric residual (host pose, target pose, affine brightness
// of both, inverse depth) against central differences on a smooth synthetic image.

#include <cmath>

#include <gtest/gtest.h>

#include "nirslam/odometry/photometric_residual.hpp"
#include "residual_jacobian_check.hpp"

namespace nirslam::odometry {
namespace {

using testing::ResidualArguments;

struct ResidualSetup {
  LevelCamera camera{300.0, 310.0, 159.5, 119.5, 320, 240};
  ImagePyramid target{testing::smooth_image(320, 240), 1};
  ResidualArguments at{SE3::exp((Vector6d() << 0.1, -0.05, 0.2, 0.02, -0.03, 0.01).finished()),
                       SE3::exp((Vector6d() << 0.15, -0.02, 0.1, 0.03, -0.01, 0.02).finished()),
                       0.1, 3.0, -0.05, 5.0, 0.5};
  double e_h = 1.0, e_t = 1.3;
  Eigen::Vector2d pixel{140.0, 100.0};
  double host_intensity = 90.0;

  bool linearize(const ResidualArguments& x, ResidualJacobian& out) const {
    const SE3 T_th = x.T_target_world * x.T_host_world.inverse();
    return linearize_residual(camera, target.level(0), T_th, T_th, pixel, x.rho, host_intensity,
                              affine_transfer(x.a_h, x.b_h, e_h, x.a_t, x.b_t, e_t), out);
  }
};

TEST(OdometryJacobians, PhotometricResidualMatchesNumericDifferentiation) {
  const ResidualSetup s;
  ResidualJacobian J;
  ASSERT_TRUE(s.linearize(s.at, J));
  testing::expect_jacobians_match_central_differences(
      J,
      [&](const ResidualArguments& x) {
        ResidualJacobian out;
        EXPECT_TRUE(s.linearize(x, out));
        return out.residual;
      },
      s.at);
  // Not all trivially zero.
  EXPECT_GT(J.d_target.head<6>().norm(), 1.0);
  EXPECT_GT(std::abs(J.d_rho), 0.1);
}

}  // namespace
}  // namespace nirslam::odometry
