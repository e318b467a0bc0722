// Relative pose error on trajectories with a known constant drift: per frame and per metre of
// travelled path, full poses and positions only.

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "nirslam/eval/trajectory_error.hpp"

namespace nirslam {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// `count` poses, each step moving `step` metres along the body's x axis, then yawing by `yaw_deg`.
std::vector<SE3> odometry(std::size_t count, double step, double yaw_deg) {
  const SE3 increment(Eigen::Matrix3d(Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ())),
                      Eigen::Vector3d(step, 0.0, 0.0));
  std::vector<SE3> poses{SE3()};
  while (poses.size() < count) poses.push_back(poses.back() * increment);
  return poses;
}

TEST(RelativeError, ConstantScaleDriftGivesKnownPerFrameAndPerMetreTranslationError) {
  // Ground truth: 0.1 m per frame, straight. Estimate: 5 % longer steps.
  const std::vector<SE3> gt = odometry(201, 0.1, 0.0);
  const std::vector<SE3> est = odometry(201, 0.105, 0.0);

  const RelativeError frame = relative_error_per_frame(est, gt);
  EXPECT_EQ(frame.translation_m.count, 200u);
  EXPECT_NEAR(frame.translation_m.mean, 0.005, 1e-12);
  EXPECT_NEAR(frame.translation_m.max, 0.005, 1e-12);
  EXPECT_NEAR(frame.rotation_deg.max, 0.0, 1e-9);

  const RelativeError metre = relative_error_per_distance(est, gt, 1.0);
  EXPECT_EQ(metre.kind, RelativeError::Kind::PerDistance);
  EXPECT_EQ(metre.translation_m.count, 191u);  // starts 0..190 reach 1 m (10 steps) before the end
  EXPECT_NEAR(metre.translation_m.mean, 0.05, 1e-9);
  EXPECT_NEAR(metre.translation_percent.mean, 5.0, 1e-7);
  EXPECT_NEAR(metre.translation_percent.max, 5.0, 1e-7);

  const RelativeError five = relative_error_per_distance(est, gt, 5.0);
  EXPECT_NEAR(five.translation_m.mean, 0.25, 1e-9);
  EXPECT_NEAR(five.translation_percent.mean, 5.0, 1e-7);  // constant drift: % does not depend on length
}

TEST(RelativeError, ConstantYawDriftGivesKnownDegreesPerFrameAndPerMetre) {
  // Ground truth turns 1 deg per 0.1 m step; the estimate turns 1.2 deg: 0.2 deg/frame, 2 deg/m.
  const std::vector<SE3> gt = odometry(101, 0.1, 1.0);
  const std::vector<SE3> est = odometry(101, 0.1, 1.2);
  const RelativeError frame = relative_error_per_frame(est, gt);
  EXPECT_NEAR(frame.rotation_deg.mean, 0.2, 1e-9);
  EXPECT_NEAR(frame.rotation_deg.max, 0.2, 1e-9);
  EXPECT_NEAR(frame.translation_m.max, 0.0, 1e-12);  // same step, rotated after it

  const RelativeError metre = relative_error_per_distance(est, gt, 1.0);
  EXPECT_NEAR(metre.rotation_deg.mean, 2.0, 1e-8);
  EXPECT_NEAR(metre.rotation_deg_per_m.mean, 2.0, 1e-8);  // over 10 ground-truth steps of 0.1 m
  EXPECT_GT(metre.translation_m.mean, 0.0);               // heading error bends the later steps

  const RelativeError every_5 = relative_error_per_frame(est, gt, 5);
  EXPECT_NEAR(every_5.rotation_deg.mean, 1.0, 1e-9);
  EXPECT_EQ(every_5.delta, 5.0);
}

TEST(RelativeError, PositionOnlyComparesDisplacementsAndHasNoRotation) {
  const std::vector<SE3> gt = odometry(51, 0.2, 0.0);
  std::vector<SE3> est;
  for (const SE3& T : gt)  // orientation garbage, positions 10 % stretched
    est.emplace_back(Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitY())), 1.1 * T.translation());
  const RelativeError frame = relative_error_per_frame(est, gt, 1, false);
  EXPECT_FALSE(frame.has_rotation);
  EXPECT_EQ(frame.rotation_deg.count, 0u);
  EXPECT_NEAR(frame.translation_m.mean, 0.02, 1e-12);
  const RelativeError metre = relative_error_per_distance(est, gt, 2.0, false);
  EXPECT_NEAR(metre.translation_percent.mean, 10.0, 1e-7);
  EXPECT_EQ(metre.rotation_deg_per_m.count, 0u);
}

TEST(RelativeError, APathShorterThanTheDistanceHasNoSegment) {
  const std::vector<SE3> gt = odometry(5, 0.1, 0.0);
  const RelativeError metre = relative_error_per_distance(gt, gt, 1.0);
  EXPECT_EQ(metre.translation_m.count, 0u);
  EXPECT_THROW(relative_error_per_distance(gt, gt, 0.0), std::invalid_argument);
  EXPECT_THROW(relative_error_per_frame(gt, gt, 0), std::invalid_argument);
  EXPECT_THROW(relative_error_per_frame(gt, odometry(4, 0.1, 0.0)), std::invalid_argument);
  EXPECT_NEAR(path_length({Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(3, 4, 0), Eigen::Vector3d(3, 4, 1)}).back(), 6.0, 1e-15);
}

}  // namespace
}  // namespace nirslam
