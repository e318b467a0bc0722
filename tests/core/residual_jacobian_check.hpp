#pragma once

// Shared by the odometry's and the illuminator's Jacobian tests: a smooth synthetic image and
// the comparison of a photometric residual's analytic Jacobians (host pose, target pose, affine
// a and b of both, inverse depth) with central differences of the residual itself.

#include <cmath>
#include <functional>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/odometry/photometric_residual.hpp"

namespace nirslam::odometry::testing {

// A smooth image (sums of sines), so bilinear interpolation's gradient matches the image's
// central-difference gradient closely enough for a numeric comparison.
inline cv::Mat smooth_image(int w, int h) {
  cv::Mat image(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      image.at<float>(y, x) = static_cast<float>(120.0 + 60.0 * std::sin(0.02 * x + 0.3) * std::cos(0.017 * y) +
                                                 30.0 * std::sin(0.011 * (x + y)));
  return image;
}

// The arguments the residual depends on: poses T_cam_world of host and target, affine
// brightness of both, the point's inverse depth.
struct ResidualArguments {
  SE3 T_host_world;
  SE3 T_target_world;
  double a_h = 0.0, b_h = 0.0, a_t = 0.0, b_t = 0.0;
  double rho = 1.0;
};

using ResidualFunction = std::function<double(const ResidualArguments&)>;

// Every analytic derivative in J against the central difference of `residual` at `x` (poses by
// a left perturbation exp(d) T). The image gradient is a central difference of a bilinear
// interpolation: the tolerance is relative (3 % plus 0.05), as DSO's own Jacobian checks allow.
inline void expect_jacobians_match_central_differences(const ResidualJacobian& J, const ResidualFunction& residual,
                                                       const ResidualArguments& x) {
  auto expect_close = [](double analytic, double numeric, const std::string& what) {
    EXPECT_NEAR(analytic, numeric, 0.03 * std::abs(numeric) + 0.05) << what;
  };
  auto central = [&](const std::function<void(ResidualArguments&, double)>& move, double eps) {
    ResidualArguments plus = x;
    ResidualArguments minus = x;
    move(plus, eps);
    move(minus, -eps);
    return (residual(plus) - residual(minus)) / (2.0 * eps);
  };
  const double pose_eps = 1e-3;
  for (int i = 0; i < 6; ++i) {
    auto along = [i](double e) {
      Vector6d d = Vector6d::Zero();
      d[i] = e;
      return SE3::exp(d);
    };
    expect_close(J.d_host[i], central([&](ResidualArguments& a, double e) { a.T_host_world = along(e) * a.T_host_world; }, pose_eps),
                 "host pose " + std::to_string(i));
    expect_close(J.d_target[i],
                 central([&](ResidualArguments& a, double e) { a.T_target_world = along(e) * a.T_target_world; }, pose_eps),
                 "target pose " + std::to_string(i));
  }
  const double affine_eps = 1e-4;
  expect_close(J.d_host[6], central([](ResidualArguments& a, double e) { a.a_h += e; }, affine_eps), "host a");
  expect_close(J.d_host[7], central([](ResidualArguments& a, double e) { a.b_h += e; }, affine_eps), "host b");
  expect_close(J.d_target[6], central([](ResidualArguments& a, double e) { a.a_t += e; }, affine_eps), "target a");
  expect_close(J.d_target[7], central([](ResidualArguments& a, double e) { a.b_t += e; }, affine_eps), "target b");
  expect_close(J.d_rho, central([](ResidualArguments& a, double e) { a.rho += e; }, pose_eps), "inverse depth");
}

}  // namespace nirslam::odometry::testing
