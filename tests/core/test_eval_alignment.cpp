// Umeyama alignment and ATE on hand-made cases: a trajectory against a rotated, translated, scaled
// (and noised) copy of itself; SE(3) on a scaled copy; alignment on the first N poses; the
// degenerate configurations.

#include <cmath>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "core/test_eval_fixtures.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/alignment.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "text_contains.hpp"

namespace nirslam {
namespace {

using eval_testing::aligned_by;
using eval_testing::example_sim3;
using eval_testing::loop_trajectory;
using eval_testing::transformed;


TEST(Umeyama, Sim3RecoversAKnownRotationTranslationAndScaleExactly) {
  const Trajectory gt = loop_trajectory(300, 30.0);
  const Sim3Transform truth = example_sim3();
  // The estimate lives in its own frame: est = truth^-1(gt), so aligning est onto gt gives truth back.
  const Trajectory est = transformed(gt, truth.inverse());
  const Sim3Transform fit = umeyama_alignment(est.positions(), gt.positions(), true);
  EXPECT_NEAR((fit.rotation - truth.rotation).norm(), 0.0, 1e-10);
  EXPECT_NEAR((fit.translation - truth.translation).norm(), 0.0, 1e-9);
  EXPECT_NEAR(fit.scale, truth.scale, 1e-12);
  EXPECT_NEAR(fit.rotation.determinant(), 1.0, 1e-12);

  const EvaluationResult r = evaluate(est, gt);
  EXPECT_EQ(r.association.pairs.size(), 300u);
  EXPECT_NEAR(r.ate_m.rmse, 0.0, 1e-9);
  EXPECT_NEAR(r.ate_m.max, 0.0, 1e-9);
  ASSERT_TRUE(r.alignment.sim3_scale.has_value());
  EXPECT_NEAR(*r.alignment.sim3_scale, 0.37, 1e-12);
  // Aligned full poses match too (rotations included), so the relative errors vanish.
  EXPECT_NEAR(r.rpe_per_frame.translation_m.max, 0.0, 1e-9);
  EXPECT_NEAR(r.rpe_per_frame.rotation_deg.max, 0.0, 1e-6);
}

TEST(Umeyama, Sim3GivesTheInjectedNoiseBack) {
  const Trajectory gt = loop_trajectory(2000, 100.0);
  const double sigma = 0.05;  // 5 cm RMS 3-D position noise: sigma / sqrt(3) per axis
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, sigma / std::sqrt(3.0));
  Trajectory noisy = gt;
  double injected_sq = 0.0;
  for (TimedPose& p : noisy.poses) {
    const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
    injected_sq += n.squaredNorm();
    p.T_world_cam = SE3(p.T_world_cam.unit_quaternion(), p.T_world_cam.translation() + n);
  }
  const double injected_rms = std::sqrt(injected_sq / static_cast<double>(gt.size()));
  // Noise added in the ground-truth frame, then the whole thing moved away by an unknown Sim(3).
  const Trajectory est = transformed(noisy, example_sim3().inverse());

  const EvaluationResult r = evaluate(est, gt, aligned_by(AlignmentMode::Sim3));
  // The fit absorbs 7 of 6000 degrees of freedom: the residual is the noise to within 0.2 %.
  EXPECT_NEAR(r.ate_m.rmse, injected_rms, 0.002 * injected_rms);
  EXPECT_NEAR(r.ate_m.rmse, sigma, 0.05 * sigma);
  EXPECT_NEAR(r.alignment.transform.scale, 0.37, 0.002);
  EXPECT_LT(r.ate_m.median, r.ate_m.rmse);
  EXPECT_GT(r.ate_m.max, 2.0 * r.ate_m.rmse);
  EXPECT_GE(r.ate_m.min, 0.0);
  EXPECT_EQ(r.position_errors_m.size(), 2000u);
}

TEST(Umeyama, Se3OnAScaledCopyReportsTheScaleError) {
  const Trajectory gt = loop_trajectory(500, 50.0);
  Sim3Transform grow = example_sim3().inverse();
  grow.scale = 1.1;  // estimate 10 % too large, and rotated and shifted
  const Trajectory est = transformed(gt, grow);

  const EvaluationResult se3 = evaluate(est, gt, aligned_by(AlignmentMode::SE3));
  EXPECT_DOUBLE_EQ(se3.alignment.transform.scale, 1.0);
  ASSERT_TRUE(se3.alignment.scale_error_percent().has_value());
  EXPECT_NEAR(*se3.alignment.scale_error_percent(), 10.0, 1e-8);
  EXPECT_GT(se3.ate_m.rmse, 0.1);  // a rigid fit cannot undo the scale

  const EvaluationResult sim3 = evaluate(est, gt, aligned_by(AlignmentMode::Sim3));
  EXPECT_NEAR(sim3.ate_m.rmse, 0.0, 1e-9);
  EXPECT_NEAR(*sim3.alignment.scale_error_percent(), 10.0, 1e-8);

  const EvaluationResult none = evaluate(est, gt, aligned_by(AlignmentMode::None));
  EXPECT_NEAR(*none.alignment.scale_error_percent(), 10.0, 1e-8);
  EXPECT_GT(none.ate_m.rmse, se3.ate_m.rmse);
}

TEST(Umeyama, AlignsOnTheFirstNPoses) {
  const Trajectory gt = loop_trajectory(400, 40.0);
  // The estimate is exact for 100 poses, then drifts away linearly in z.
  Trajectory est = gt;
  for (std::size_t k = 100; k < est.size(); ++k) {
    const Eigen::Vector3d drift(0.0, 0.0, 0.01 * static_cast<double>(k - 100));
    est.poses[k].T_world_cam = SE3(est.poses[k].T_world_cam.unit_quaternion(), est.poses[k].T_world_cam.translation() + drift);
  }
  est = transformed(est, example_sim3());
  const EvaluationResult first = evaluate(est, gt, aligned_by(AlignmentMode::Sim3, 100));
  EXPECT_EQ(first.alignment.pairs_used, 100u);
  for (std::size_t k = 0; k < 100; ++k) EXPECT_NEAR(first.position_errors_m[k], 0.0, 1e-9);
  EXPECT_NEAR(first.position_errors_m.back(), 0.01 * 299, 1e-9);  // the drift shows undiluted
  EXPECT_TRUE(contains(evaluation_headline(first), "on the first 100 of 400 pairs")) << evaluation_headline(first);
  const EvaluationResult all = evaluate(est, gt, aligned_by(AlignmentMode::Sim3));
  EXPECT_LT(all.position_errors_m.back(), first.position_errors_m.back());  // spread over everything
  EXPECT_EQ(evaluate(est, gt, aligned_by(AlignmentMode::Sim3, 100000)).alignment.pairs_used, 400u);
  EXPECT_THROW(evaluate(est, gt, aligned_by(AlignmentMode::Sim3, 2)), InputError);
}

TEST(Umeyama, ReflectedPointsStillGiveAProperRotation) {
  const Trajectory gt = loop_trajectory(100, 10.0);
  std::vector<Eigen::Vector3d> mirrored = gt.positions();
  for (auto& p : mirrored) p.x() = -p.x();
  const Sim3Transform fit = umeyama_alignment(mirrored, gt.positions(), true);
  EXPECT_NEAR(fit.rotation.determinant(), 1.0, 1e-12);  // Umeyama's S = diag(1, 1, -1) case
  EXPECT_NEAR((fit.rotation.transpose() * fit.rotation - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
}

TEST(Umeyama, DegenerateConfigurationsAreDetected) {
  std::vector<Eigen::Vector3d> line, point, plane;
  for (int k = 0; k < 50; ++k) {
    line.emplace_back(0.1 * k, 0.2 * k, -0.05 * k);
    point.emplace_back(1.0, 2.0, 3.0);
    plane.emplace_back(std::cos(0.1 * k), std::sin(0.1 * k), 0.0);
  }
  ASSERT_TRUE(alignment_degeneracy(line).has_value());
  EXPECT_TRUE(contains(*alignment_degeneracy(line), "one straight line"));
  EXPECT_TRUE(contains(*alignment_degeneracy(point), "at one place"));
  EXPECT_TRUE(contains(*alignment_degeneracy({line[0], line[1]}), "only 2 point(s)"));
  EXPECT_FALSE(alignment_degeneracy(plane).has_value());  // planar is fine: 3 non-collinear points
  EXPECT_THROW(umeyama_alignment(line, line, true), std::invalid_argument);
  EXPECT_THROW(umeyama_alignment(plane, line, false), std::invalid_argument);

  // Through evaluate: a straight-line estimate names its file and the reason.
  Trajectory gt, est;
  for (int k = 0; k < 50; ++k) {
    gt.poses.push_back({k * 0.1, SE3(Eigen::Quaterniond::Identity(), line[static_cast<std::size_t>(k)])});
    est.poses.push_back({k * 0.1, SE3(Eigen::Quaterniond::Identity(), 2.0 * line[static_cast<std::size_t>(k)])});
  }
  est.source = "straight.txt";
  try {
    evaluate(est, gt, aligned_by(AlignmentMode::Sim3));
    FAIL() << "collinear accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), std::filesystem::path("straight.txt"));
    EXPECT_TRUE(contains(e.what(), "one straight line")) << e.what();
    EXPECT_TRUE(contains(e.what(), "on the 50 matched pairs")) << e.what();
  }
  // Without alignment the straight line is fine, and the ATE is the plain distance.
  const EvaluationResult none = evaluate(est, gt, aligned_by(AlignmentMode::None));
  EXPECT_NEAR(none.position_errors_m.back(), line.back().norm(), 1e-12);
  EXPECT_FALSE(none.alignment.sim3_scale.has_value());
}

TEST(ErrorStatistics, SummarisesAKnownSet) {
  const ErrorStatistics s = summarize_errors({3.0, 1.0, 4.0, 1.0, 5.0, 9.0});
  EXPECT_EQ(s.count, 6u);
  EXPECT_DOUBLE_EQ(s.mean, 23.0 / 6.0);
  EXPECT_DOUBLE_EQ(s.median, 3.5);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(133.0 / 6.0));
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 9.0);
  EXPECT_NEAR(s.std, std::sqrt(133.0 / 6.0 - (23.0 / 6.0) * (23.0 / 6.0)), 1e-12);
  EXPECT_DOUBLE_EQ(summarize_errors({2.0, 7.0, 1.0}).median, 2.0);
  EXPECT_EQ(summarize_errors({}).count, 0u);
}

}  // namespace
}  // namespace nirslam
