// The analytic Jacobians of the photometric residual (host pose, target pose, affine brightness
// of both, inverse depth) against central differences on a smooth synthetic image.

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/odometry/photometric_residual.hpp"

namespace nirslam::odometry {
namespace {

// A smooth image (sums of sines), so bilinear interpolation's gradient matches the image's
// central-difference gradient closely enough for a numeric comparison.
cv::Mat smooth_image(int w, int h) {
  cv::Mat image(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      image.at<float>(y, x) = static_cast<float>(120.0 + 60.0 * std::sin(0.02 * x + 0.3) * std::cos(0.017 * y) +
                                                 30.0 * std::sin(0.011 * (x + y)));
  return image;
}

struct ResidualSetup {
  LevelCamera camera{300.0, 310.0, 159.5, 119.5, 320, 240};
  ImagePyramid target{smooth_image(320, 240), 1};
  SE3 T_host_world = SE3::exp((Vector6d() << 0.1, -0.05, 0.2, 0.02, -0.03, 0.01).finished());
  SE3 T_target_world = SE3::exp((Vector6d() << 0.15, -0.02, 0.1, 0.03, -0.01, 0.02).finished());
  double a_h = 0.1, b_h = 3.0, a_t = -0.05, b_t = 5.0, e_h = 1.0, e_t = 1.3;
  Eigen::Vector2d pixel{140.0, 100.0};
  double rho = 0.5;
  double host_intensity = 90.0;

  double residual(const SE3& Th, const SE3& Tt, double ah, double bh, double at, double bt, double r) const {
    ResidualJacobian out;
    const SE3 T_th = Tt * Th.inverse();
    EXPECT_TRUE(linearize_residual(camera, target.level(0), T_th, T_th, pixel, r, host_intensity,
                                   affine_transfer(ah, bh, e_h, at, bt, e_t), out));
    return out.residual;
  }
};

TEST(OdometryJacobians, PhotometricResidualMatchesNumericDifferentiation) {
  ResidualSetup s;
  ResidualJacobian J;
  const SE3 T_th = s.T_target_world * s.T_host_world.inverse();
  ASSERT_TRUE(linearize_residual(s.camera, s.target.level(0), T_th, T_th, s.pixel, s.rho, s.host_intensity,
                                 affine_transfer(s.a_h, s.b_h, s.e_h, s.a_t, s.b_t, s.e_t), J));
  const double eps = 1e-3;
  // The image gradient is a central difference of a bilinear interpolation: compare with a
  // relative tolerance that allows for that, as DSO's own Jacobian checks do.
  auto expect_close = [](double analytic, double numeric, const char* what, int i) {
    EXPECT_NEAR(analytic, numeric, 0.03 * std::abs(numeric) + 0.05) << what << " " << i;
  };
  for (int i = 0; i < 6; ++i) {
    Vector6d d = Vector6d::Zero();
    d[i] = eps;
    const double rp = s.residual(SE3::exp(d) * s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t, s.rho);
    const double rm = s.residual(SE3::exp(-d) * s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t, s.rho);
    expect_close(J.d_host[i], (rp - rm) / (2 * eps), "host pose", i);
    const double tp = s.residual(s.T_host_world, SE3::exp(d) * s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t, s.rho);
    const double tm = s.residual(s.T_host_world, SE3::exp(-d) * s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t, s.rho);
    expect_close(J.d_target[i], (tp - tm) / (2 * eps), "target pose", i);
  }
  const double e2 = 1e-4;
  expect_close(J.d_host[6],
               (s.residual(s.T_host_world, s.T_target_world, s.a_h + e2, s.b_h, s.a_t, s.b_t, s.rho) -
                s.residual(s.T_host_world, s.T_target_world, s.a_h - e2, s.b_h, s.a_t, s.b_t, s.rho)) / (2 * e2),
               "host a", 6);
  expect_close(J.d_host[7],
               (s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h + e2, s.a_t, s.b_t, s.rho) -
                s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h - e2, s.a_t, s.b_t, s.rho)) / (2 * e2),
               "host b", 7);
  expect_close(J.d_target[6],
               (s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t + e2, s.b_t, s.rho) -
                s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t - e2, s.b_t, s.rho)) / (2 * e2),
               "target a", 6);
  expect_close(J.d_target[7],
               (s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t + e2, s.rho) -
                s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t - e2, s.rho)) / (2 * e2),
               "target b", 7);
  expect_close(J.d_rho,
               (s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t, s.rho + eps) -
                s.residual(s.T_host_world, s.T_target_world, s.a_h, s.b_h, s.a_t, s.b_t, s.rho - eps)) / (2 * eps),
               "inverse depth", 0);
  // Not all trivially zero.
  EXPECT_GT(J.d_target.head<6>().norm(), 1.0);
  EXPECT_GT(std::abs(J.d_rho), 0.1);
}

}  // namespace
}  // namespace nirslam::odometry
