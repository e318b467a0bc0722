// The lamp's beam separated from the halo factor with a known lens vignetting (issue 8).
#include <cmath>
#include <cstdio>
#include <iostream>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/photometric/beam_from_halo.hpp"
#include "nirslam/photometric/beam_halo.hpp"
#include "nirslam/photometric/given_calibration.hpp"
#include "nirslam/photometric/response_model.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam {
namespace {

// The simulator's camera: 640x480, 75 degrees across.
PinholeCamera wide_camera() {
  const double f = 320.0 / std::tan(37.5 * M_PI / 180.0);
  return PinholeCamera(640, 480, Eigen::Vector4d(f, f, 319.5, 239.5));
}

TEST(BeamFromHalo, RecoversTheBeamOfAnExactHalo) {
  const PinholeCamera camera = wide_camera();
  const cv::Mat lens = VignetteModel{Eigen::Vector3d(-0.35, 0.10, -0.05)}.render(640, 480);
  const double m = std::log(0.5) / std::log(std::cos(30.0 * M_PI / 180.0));  // a 30 degree beam: 4.82
  const cv::Mat halo = halo_with_beam(lens, camera, m) * 0.8;  // any scale
  const BeamFit fit = fit_beam_from_halo(halo, lens * 65535.0, camera);
  ASSERT_TRUE(fit.ok) << fit.reason;
  EXPECT_NEAR(fit.beam_exponent, m, 1e-3);
  EXPECT_NEAR(fit.half_angle_deg, 30.0, 0.01);
  EXPECT_LT(fit.rms_log, 1e-4);
  EXPECT_GT(fit.max_alpha_deg, 40.0);
  const cv::Mat pattern = beam_pattern(halo, lens);
  EXPECT_NEAR(pattern.at<float>(240, 320), 1.0, 1e-3);
  EXPECT_NEAR(pattern.at<float>(0, 0), std::pow(camera.unproject(Eigen::Vector2d(0, 0))->normalized().z(), m), 1e-3);
}

TEST(BeamFromHalo, FromTheSimulatorsHaloFactor) {
  // Simulator::halo_factor() is V x B fitted by the radial polynomial the calibration estimates:
  // what a perfect calibration under the lamp would give.
  SimulatorOptions o;
  const Simulator sim(o);
  const cv::Mat halo = sim.halo_factor().render(o.width, o.height);
  const cv::Mat lens = o.vignette.render(o.width, o.height);
  const BeamFit fit = fit_beam_from_halo(halo, lens, *sim.camera());
  ASSERT_TRUE(fit.ok) << fit.reason;
  const double m = sim.lighting(50.0).illuminator.beam_exponent();
  std::cout << "m " << fit.beam_exponent << " (truth " << m << "), half angle " << fit.half_angle_deg << " deg, rms log "
            << fit.rms_log << "\n";
  // Measured 4.828 against 4.819 (half angle 29.97 degrees, rms 0.013 in log): the polynomial
  // in r^2 follows cos(alpha)^m closely but not exactly over the whole image.
  EXPECT_NEAR(fit.beam_exponent, m, 0.02 * m);
  EXPECT_NEAR(fit.half_angle_deg, o.beam_half_angle_deg, 0.3);
}

TEST(BeamFromHalo, HaloOfALensVignetteUnderABeam) {
  const PinholeCamera camera = wide_camera();
  const cv::Mat lens = VignetteModel{Eigen::Vector3d(-0.35, 0.10, -0.05)}.render(640, 480);
  const double m = 4.82;
  const cv::Mat halo = halo_with_beam(lens, camera, m);
  ASSERT_EQ(halo.type(), CV_32FC1);
  // On the axis the beam is 1; at a corner (alpha = atan(|x - c| / f)) cos(alpha)^m.
  EXPECT_NEAR(halo.at<float>(239, 319), lens.at<float>(239, 319), 1e-4);
  const double f = camera.intrinsics()[0];
  const double corner_cos = f / std::sqrt(f * f + 319.5 * 319.5 + 239.5 * 239.5);
  EXPECT_NEAR(halo.at<float>(0, 0), lens.at<float>(0, 0) * std::pow(corner_cos, m), 1e-4);
  // The simulator renders its frames with the lens vignette times this beam, and its
  // halo_factor() is that product fitted by the radial polynomial: the same curve.
  SimulatorOptions o;
  const Simulator sim(o);
  const VignetteFit fitted = fit_vignette_to_image(
      halo_with_beam(o.vignette.render(o.width, o.height), *sim.camera(), sim.lighting(50.0).illuminator.beam_exponent()));
  // The corner differs most (0.015 measured): the simulator fits along the diagonal with V(0) = 1,
  // fit_vignette_to_image over the image's area with a free scale, where few pixels reach r = 1.
  for (int i = 0; i <= 10; ++i)
    EXPECT_NEAR(fitted.vignette(i / 10.0), sim.halo_factor()(i / 10.0), i < 10 ? 0.01 : 0.02) << "r " << i / 10.0;
  EXPECT_THROW(halo_with_beam(VignetteModel{}.render(320, 240), camera, m), std::invalid_argument);
}

// The floor under the lamp-lit vignette error: the true halo factor V B is not a sextic in r, so
// the polynomial the back end estimates (and the ground truth it is compared with,
// Simulator::halo_factor()) differs from it by this much, measured the way
// compare_with_ground_truth does (both scaled to their maximum, every 4th pixel). Measured: mean
// 0.0048, max 0.018 at the default 30-degree beam (issue 6's vignette target is 0.005); 0.0010 /
// 0.004 at 45 degrees.
TEST(BeamFromHalo, TheRadialPolynomialHoldsTheHaloFactorToAFloor) {
  for (const double half_angle : {30.0, 45.0}) {
    SimulatorOptions o;
    o.beam_half_angle_deg = half_angle;
    const Simulator sim(o);
    const cv::Mat exact = halo_with_beam(o.vignette.render(o.width, o.height), *sim.camera(),
                                         sim.lighting(50.0).illuminator.beam_exponent());
    const cv::Mat fitted = sim.halo_factor().render(o.width, o.height);
    double exact_max = 0.0, fitted_max = 0.0;
    cv::minMaxLoc(exact, nullptr, &exact_max);
    cv::minMaxLoc(fitted, nullptr, &fitted_max);
    double mean = 0.0, max = 0.0;
    int count = 0;
    for (int y = 0; y < o.height; y += 4)
      for (int x = 0; x < o.width; x += 4, ++count) {
        const double d = std::abs(fitted.at<float>(y, x) / fitted_max - exact.at<float>(y, x) / exact_max);
        mean += d;
        max = std::max(max, d);
      }
    mean /= count;
    std::printf("beam half angle %.0f deg: the sextic against V B, mean %.4f, max %.4f\n", half_angle, mean, max);
    if (half_angle < 40.0) {
      EXPECT_GT(mean, 0.003);
      EXPECT_LT(mean, 0.007);
    } else {
      EXPECT_LT(mean, 0.002);
    }
  }
}

TEST(BeamHalo, IsTheSimulatorsHaloFactorWithItsDerivative) {
  SimulatorOptions o;
  const Simulator sim(o);
  const double m = sim.lighting(50.0).illuminator.beam_exponent();
  const BeamHalo beam = beam_halo_for_camera(*sim.camera(), o.vignette, 3.0);
  EXPECT_DOUBLE_EQ(beam.initial_exponent(), 3.0);
  // The same construction as Simulator::halo_factor() (the diagonal, V(0) = 1, least squares).
  EXPECT_LT((beam.vignette(m) - sim.halo_factor().v).norm(), 1e-6) << beam.vignette(m).transpose();
  // Without a beam: the lens vignette itself, which the polynomial holds exactly.
  EXPECT_LT((beam.vignette(0.0) - o.vignette.v).norm(), 1e-9);
  for (const double at : {0.5, 2.0, 4.82, 9.0}) {
    Eigen::Vector3d analytic;
    beam.vignette(at, &analytic);
    const double h = 1e-6;
    const Eigen::Vector3d numeric = (beam.vignette(at + h) - beam.vignette(at - h)) / (2.0 * h);
    EXPECT_LT((analytic - numeric).norm(), 1e-6 * (1.0 + numeric.norm())) << "m " << at;
  }
  EXPECT_THROW(BeamHalo(o.vignette, {0.1, 0.2}, {0.9, 0.8}, 2.0), std::invalid_argument);
  EXPECT_THROW(BeamHalo(o.vignette, {0.1, 0.2, 0.3, 0.4}, {0.9, 0.8, 0.0, 0.7}, 2.0), std::invalid_argument);
}

TEST(BeamFromHalo, NoBeamOrNoAngleSaysWhy) {
  const PinholeCamera camera = wide_camera();
  const cv::Mat lens = VignetteModel{Eigen::Vector3d(-0.35, 0.10, -0.05)}.render(640, 480);
  const BeamFit none = fit_beam_from_halo(lens, lens, camera);  // the lamp off: H = V
  EXPECT_FALSE(none.ok);
  EXPECT_NE(none.reason.find("not darker"), std::string::npos) << none.reason;
  // A telephoto lens: every pixel within 3 degrees of the axis.
  const PinholeCamera narrow(640, 480, Eigen::Vector4d(8000.0, 8000.0, 319.5, 239.5));
  const BeamFit central = fit_beam_from_halo(lens, lens, narrow);
  EXPECT_FALSE(central.ok);
  EXPECT_NE(central.reason.find("too central"), std::string::npos) << central.reason;
  try {
    fit_beam_from_halo(lens, VignetteModel{}.render(320, 240), camera);
    FAIL() << "sizes differ";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("320x240"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nirslam
