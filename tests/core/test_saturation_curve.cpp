// The entropy-vs-power curve: analytic Jacobians against central differences, the closed-form
// inverse, and the fit recovering known parameters from exact and from noisy samples.

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/illumination/saturation_curve.hpp"

namespace nirslam {
namespace {

const std::vector<double> kPowers{0, 20, 40, 50, 70, 100, 125, 150};

// The curve with its parameters (h0, h_max, ln p_s, beta) moved by `delta`.
SaturationCurve moved(const SaturationCurve& c, const Eigen::Vector4d& delta) {
  return {c.h0_bits + delta[0], c.h_max_bits + delta[1], c.p_s_w * std::exp(delta[2]), c.beta + delta[3]};
}

const SaturationCurve kCurves[] = {{1.8, 7.4, 22.0, 1.0}, {3.1, 6.2, 75.0, 1.0}, {0.2, 7.9, 5.0, 0.45},
                                   {6.0, 5.0, 40.0, 1.7}, {2.5, 7.6, 18.0, 0.6}};

TEST(SaturationCurve, JacobianMatchesCentralDifferences) {
  const double h = 1e-6;
  for (const SaturationCurve& curve : kCurves) {
    for (const double p : {0.0, 3.0, 20.0, 64.0, 150.0}) {
      const Eigen::Vector4d analytic = curve.jacobian(p);
      Eigen::Vector4d numeric;
      for (int i = 0; i < 4; ++i) {
        const Eigen::Vector4d d = Eigen::Vector4d::Unit(i) * h;
        numeric[i] = (moved(curve, d)(p) - moved(curve, -d)(p)) / (2 * h);
      }
      EXPECT_LT((analytic - numeric).norm(), 1e-7) << "beta " << curve.beta << ", P = " << p << "\n"
                                                   << analytic.transpose() << "\n" << numeric.transpose();
    }
  }
}

TEST(SaturationCurve, PowerForShareIsTheInverseAndItsJacobianMatchesDifferences) {
  for (const SaturationCurve& curve : kCurves) {
    if (curve.h0_bits >= curve.h_max_bits) continue;
    for (const double share : {0.9, 0.95, 0.98, 0.995}) {
      const double p = curve.power_for_share(share);
      EXPECT_NEAR(curve(p), share * curve.h_max_bits, 1e-12);
      const double h = 1e-6;
      Eigen::Vector4d numeric;
      for (int i = 0; i < 4; ++i) {
        const Eigen::Vector4d d = Eigen::Vector4d::Unit(i) * h;
        numeric[i] = (moved(curve, d).power_for_share(share) - moved(curve, -d).power_for_share(share)) / (2 * h);
      }
      EXPECT_LT((curve.power_for_share_jacobian(share) - numeric).norm(), 1e-5 * numeric.norm()) << curve.beta;
    }
  }
  const SaturationCurve exponential{1.8, 7.4, 22.0};
  EXPECT_NEAR(exponential.power_for_share(0.98), 22.0 * std::log((7.4 - 1.8) / (0.02 * 7.4)), 1e-12);
  // Already on the plateau without light (daylight): no power needed.
  const SaturationCurve bright{7.3, 7.4, 30.0};
  EXPECT_DOUBLE_EQ(bright.power_for_share(0.98), 0.0);
  EXPECT_EQ(bright.power_for_share_jacobian(0.98), Eigen::Vector4d::Zero());
}

TEST(SaturationFit, RecoversExactParameters) {
  const SaturationCurve truth{1.8, 7.4, 22.0};
  std::vector<CurveSample> samples;
  for (double p : kPowers) samples.push_back({p, truth(p), 30.0});
  const auto fit = fit_saturation_curve(samples);
  ASSERT_TRUE(fit);
  EXPECT_TRUE(fit->converged);
  EXPECT_EQ(fit->model, CurveModel::Exponential) << "the stretched model earns nothing on exponential data";
  EXPECT_DOUBLE_EQ(fit->curve.beta, 1.0);
  EXPECT_NEAR(fit->curve.h0_bits, 1.8, 1e-6);
  EXPECT_NEAR(fit->curve.h_max_bits, 7.4, 1e-6);
  EXPECT_NEAR(fit->curve.p_s_w, 22.0, 1e-5);
  EXPECT_LT(fit->rms_residual_bits, 1e-8);
  EXPECT_FALSE(fit->plateau_at_bound);
  EXPECT_FALSE(fit->scale_at_bound);
}

TEST(SaturationFit, RecoversParametersFromNoisySamplesWithinItsOwnUncertainty) {
  // 200 sweeps with 0.03 bits of noise per point: the errors of P_s scatter as the fit's covariance
  // says, and the true value lies within two standard deviations in about 95 % of the sweeps.
  const SaturationCurve truth{2.1, 7.2, 28.0};
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.03);
  int inside = 0;
  double squared_z = 0.0;
  double mean_error = 0.0;
  constexpr int kTrials = 200;
  for (int trial = 0; trial < kTrials; ++trial) {
    std::vector<CurveSample> samples;
    for (double p : kPowers) samples.push_back({p, truth(p) + noise(rng), 1.0});
    const auto fit = fit_saturation_curve(samples, CurveModel::Exponential);
    ASSERT_TRUE(fit);
    ASSERT_TRUE(fit->covariance);
    const double sigma_log_ps = std::sqrt((*fit->covariance)(2, 2));
    const double z = std::log(fit->curve.p_s_w / truth.p_s_w) / sigma_log_ps;
    inside += std::abs(z) < 2.0 ? 1 : 0;
    squared_z += z * z;
    mean_error += (fit->curve.h_max_bits - truth.h_max_bits) / kTrials;
    EXPECT_NEAR(fit->rms_residual_bits, 0.03, 0.025);
  }
  EXPECT_GE(inside, static_cast<int>(0.88 * kTrials));
  EXPECT_NEAR(std::sqrt(squared_z / kTrials), 1.0, 0.35) << "the covariance describes the scatter";
  EXPECT_NEAR(mean_error, 0.0, 0.01) << "no bias in the plateau";
}

TEST(SaturationFit, SweepsThatStopEarlyAreFitButFlagged) {
  const SaturationCurve truth{1.5, 7.5, 40.0};
  std::vector<CurveSample> exact;
  for (double p : {0.0, 20.0, 40.0, 50.0}) exact.push_back({p, truth(p), 1.0});
  const auto fit = fit_saturation_curve(exact);
  ASSERT_TRUE(fit);
  EXPECT_NEAR(fit->curve.p_s_w, 40.0, 1e-3);  // noise-free data still pins the curve down
  // A straight line has no plateau: the fit hits a bound and says so.
  std::vector<CurveSample> line;
  for (double p : kPowers) line.push_back({p, 1.0 + 0.02 * p, 1.0});
  const auto linear = fit_saturation_curve(line);
  ASSERT_TRUE(linear);
  EXPECT_TRUE(linear->plateau_at_bound || linear->scale_at_bound);
  EXPECT_LE(linear->curve.h_max_bits, 8.0);
}

TEST(SaturationFit, RecoversAStretchedCurveAndPrefersItOnlyWhenItFitsClearlyBetter) {
  // A deep scene: fast rise, long tail (beta 0.5).
  const SaturationCurve truth{3.2, 7.9, 15.0, 0.5};
  std::vector<CurveSample> samples;
  for (double p : kPowers) samples.push_back({p, truth(p), 3.0});
  const auto fit = fit_saturation_curve(samples);
  ASSERT_TRUE(fit);
  EXPECT_EQ(fit->model, CurveModel::StretchedExponential);
  EXPECT_NEAR(fit->curve.beta, 0.5, 1e-4);
  EXPECT_NEAR(fit->curve.p_s_w, 15.0, 1e-2);
  EXPECT_NEAR(fit->curve.h_max_bits, 7.9, 1e-4);
  ASSERT_TRUE(fit->exponential_rms_bits);
  EXPECT_GT(*fit->exponential_rms_bits, 0.05) << "the plain exponential cannot follow this shape";
  EXPECT_EQ(fit->parameters, 4);

  // Exponential data with noise: the extra parameter does not pay for itself (in most sweeps).
  const SaturationCurve plain{2.0, 7.3, 25.0};
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.03);
  int stretched = 0;
  for (int trial = 0; trial < 100; ++trial) {
    std::vector<CurveSample> noisy;
    for (double p : kPowers) noisy.push_back({p, plain(p) + noise(rng), 1.0});
    stretched += fit_saturation_curve(noisy)->model == CurveModel::StretchedExponential ? 1 : 0;
  }
  EXPECT_LT(stretched, 15);
  // Too few powers for the stretched model: the exponential, however it fits.
  std::vector<CurveSample> five;
  for (double p : {0.0, 20.0, 40.0, 70.0, 150.0}) five.push_back({p, truth(p), 1.0});
  EXPECT_EQ(fit_saturation_curve(five)->model, CurveModel::Exponential);
}

TEST(SaturationFit, NeedsThreeDistinctPowersAndValidSamples) {
  EXPECT_FALSE(fit_saturation_curve(std::vector<CurveSample>{{0, 2}, {10, 4}}));
  EXPECT_FALSE(fit_saturation_curve(std::vector<CurveSample>{{0, 2}, {10, 4}, {10, 4.1}, {0, 2.1}}));
  const auto three = fit_saturation_curve(std::vector<CurveSample>{{0, 2}, {10, 4}, {40, 6}});
  ASSERT_TRUE(three);
  EXPECT_FALSE(three->covariance) << "no degree of freedom left for an uncertainty";
  EXPECT_THROW(fit_saturation_curve(std::vector<CurveSample>{{-1, 2}, {10, 4}, {40, 6}}), std::invalid_argument);
  EXPECT_THROW(fit_saturation_curve(std::vector<CurveSample>{{0, NAN}, {10, 4}, {40, 6}}), std::invalid_argument);
}

}  // namespace
}  // namespace nirslam
