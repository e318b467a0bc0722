// Timestamp association: different rates, jitter within the tolerance, gaps, one-to-one pairing,
// interpolation, and the errors for no overlap and too few pairs. The real EuRoC ground truth
// (200 Hz) is paired with the 20 Hz camera timestamps of the same sequence.

#include <cmath>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "core/test_eval_fixtures.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/association.hpp"
#include "nirslam/sources/euroc_reader.hpp"
#include "text_contains.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

// Positions that encode the time (x = t), so a wrong pairing shows in the positions.
Trajectory timeline(double t0, double rate_hz, std::size_t count) {
  Trajectory t;
  for (std::size_t k = 0; k < count; ++k) {
    const double stamp = t0 + static_cast<double>(k) / rate_hz;
    t.poses.push_back({stamp, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(stamp - t0, 0.0, 0.0))});
  }
  return t;
}

AssociationOptions tolerance(double max_dt_s) {
  AssociationOptions options;
  options.max_dt_s = max_dt_s;
  return options;
}

AssociationOptions offset(double time_offset_s) {
  AssociationOptions options;
  options.time_offset_s = time_offset_s;
  return options;
}

AssociationOptions interpolating(double max_gap_s = 0.1) {
  AssociationOptions options;
  options.method = AssociationMethod::Interpolate;
  options.max_interpolation_gap_s = max_gap_s;
  return options;
}


TEST(Association, PairsA20HzEstimateWithA200HzGroundTruthDespiteJitter) {
  const Trajectory gt = timeline(1000.0, 200.0, 2000);  // 10 s
  Trajectory est;
  // 20 Hz, each stamp off its ground-truth stamp by up to +-2.4 ms (within half a GT period, so the
  // nearest ground-truth pose is the intended one), starting 1 s late.
  for (std::size_t k = 0; k < 150; ++k) {
    const double jitter = 0.0024 * std::sin(static_cast<double>(k) * 1.7);
    const double stamp = 1001.0 + static_cast<double>(k) * 0.05 + jitter;
    est.poses.push_back({stamp, SE3()});
  }
  const Association a = associate(est, gt);
  ASSERT_EQ(a.pairs.size(), 150u);
  EXPECT_EQ(a.estimate_count, 150u);
  EXPECT_EQ(a.ground_truth_count, 2000u);
  EXPECT_EQ(a.unmatched_inside_overlap, 0u);
  EXPECT_LE(a.max_abs_dt_s, 0.0024 + 1e-9);
  for (std::size_t k = 0; k < a.pairs.size(); ++k) {
    EXPECT_EQ(a.pairs[k].estimate_index, k);
    EXPECT_EQ(a.pairs[k].ground_truth_index, 200 + 10 * k) << k;
    EXPECT_NEAR(std::abs(a.pairs[k].dt_s), std::abs(0.0024 * std::sin(static_cast<double>(k) * 1.7)), 1e-9);
  }
}

TEST(Association, LeavesPosesInAGroundTruthGapUnmatchedAndCountsThem) {
  Trajectory gt = timeline(0.0, 100.0, 1000);  // 10 s at 100 Hz
  // A 2 s gap (the total station lost the prism): remove 3.0 s < t < 5.0 s.
  std::erase_if(gt.poses, [](const TimedPose& p) { return p.timestamp_s > 3.0 + 1e-9 && p.timestamp_s < 5.0 - 1e-9; });
  const Trajectory est = timeline(0.013, 10.0, 100);  // 10 Hz, 13 ms after the GT grid
  const Association a = associate(est, gt, tolerance(0.02));
  // Estimated stamps end in .x13. Those from 3.113 to 4.913 s (k = 31..49, 19 poses) have no ground
  // truth within 20 ms; 3.013 s still pairs with 3.000 s (13 ms).
  EXPECT_EQ(a.pairs.size(), 100u - 19u);
  EXPECT_EQ(a.unmatched_inside_overlap, 19u);
  for (const PosePair& p : a.pairs) {
    EXPECT_FALSE(p.timestamp_s > 3.02 && p.timestamp_s < 4.98) << p.timestamp_s;
    // 13 ms after the 10 ms grid: the nearest stamp is 3 ms before (13 ms at the gap's edge).
    EXPECT_NEAR(p.dt_s, p.estimate_index == 30 ? 0.013 : 0.003, 1e-9) << p.estimate_index;
  }
}

TEST(Association, IsOneToOneWhenTheEstimateIsDenser) {
  const Trajectory gt = timeline(0.0, 20.0, 100);      // 20 Hz
  const Trajectory est = timeline(0.0004, 200.0, 1000);  // 200 Hz
  const Association a = associate(est, gt);
  ASSERT_EQ(a.pairs.size(), 100u);  // each ground-truth pose once
  std::set<std::size_t> used_gt;
  for (const PosePair& p : a.pairs) {
    EXPECT_TRUE(used_gt.insert(p.ground_truth_index).second) << "ground truth used twice";
    EXPECT_NEAR(p.dt_s, 0.0004, 1e-9);  // the nearest estimated pose won
    EXPECT_EQ(p.estimate_index, 10 * p.ground_truth_index);
  }
  // 990 estimated stamps lie inside [0, 4.95] s; 99 of them are matched (the 100th match, 4.9504 s,
  // is just past the ground truth's end).
  EXPECT_EQ(a.unmatched_inside_overlap, 990u - 99u);
}

TEST(Association, TimeOffsetShiftsTheEstimate) {
  const Trajectory gt = timeline(0.0, 10.0, 50);
  const Trajectory est = timeline(0.5, 10.0, 40);  // its clock runs 0.5 s ahead
  const Association shifted = associate(est, gt, offset(-0.5));
  EXPECT_EQ(shifted.pairs.size(), 40u);
  EXPECT_EQ(shifted.pairs.front().ground_truth_index, 0u);
}

TEST(Association, InterpolatesDenseGroundTruthAtTheEstimatedStamps) {
  // Ground truth moving at 2 m/s along x, 200 Hz, rotating at 1 rad/s about z.
  Trajectory gt;
  for (int k = 0; k < 400; ++k) {
    const double t = k * 0.005;
    gt.poses.push_back({t, SE3(Eigen::Matrix3d(Eigen::AngleAxisd(t, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(2 * t, 0, 0))});
  }
  Trajectory est;
  for (int k = 0; k < 30; ++k) est.poses.push_back({0.0123 + k * 0.05, SE3()});
  const Association nearest = associate(est, gt);
  const Association interpolated = associate(est, gt, interpolating());
  ASSERT_EQ(nearest.pairs.size(), 30u);
  ASSERT_EQ(interpolated.pairs.size(), 30u);
  for (std::size_t k = 0; k < 30; ++k) {
    const double t = est.poses[k].timestamp_s;
    const PosePair& p = interpolated.pairs[k];
    EXPECT_TRUE(p.interpolated);
    EXPECT_NEAR((p.T_world_cam_ground_truth.translation() - Eigen::Vector3d(2 * t, 0, 0)).norm(), 0.0, 1e-9);
    EXPECT_NEAR(so3_log(p.T_world_cam_ground_truth.rotation_matrix()).z(), t, 1e-9);
    // Nearest is off by the 2.3 ms to the nearest stamp, i.e. 4.6 mm at 2 m/s.
    EXPECT_NEAR((nearest.pairs[k].T_world_cam_ground_truth.translation() - Eigen::Vector3d(2 * t, 0, 0)).norm(), 0.0046, 1e-9);
  }
  // Not across a gap wider than max_interpolation_gap_s.
  EXPECT_THROW(associate(est, gt, interpolating(0.001)), InputError);
  EXPECT_FALSE(interpolate_pose(gt, -1.0).has_value());
  ASSERT_TRUE(interpolate_pose(gt, 1.0012).has_value());
  EXPECT_NEAR(interpolate_pose(gt, 1.0012)->translation().x(), 2.0024, 1e-9);
}

TEST(Association, NoOverlapInTimeIsAClearError) {
  Trajectory gt = timeline(1403715274.3, 200.0, 800);
  gt.source = "groundtruth.txt";
  Trajectory est = timeline(1403715290.0, 20.0, 60);
  est.source = "estimate.txt";
  try {
    associate(est, gt);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), fs::path("estimate.txt"));
    EXPECT_TRUE(contains(e.what(), "no overlap in time with the ground truth groundtruth.txt")) << e.what();
    EXPECT_TRUE(contains(e.what(), "[1403715290.000000, 1403715292.950000] s")) << e.what();
    EXPECT_TRUE(contains(e.what(), "[1403715274.300000, 1403715278.295000] s")) << e.what();
  }
  // Nanoseconds against seconds gets a hint.
  Trajectory ns = timeline(1.4037152743e18, 1e-7, 10);
  try {
    associate(ns, gt);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "nanoseconds")) << e.what();
  }
}

TEST(Association, OverlapWithoutPairsAndTooFewPairsAreClearErrors) {
  const Trajectory gt = timeline(0.0, 10.0, 100);
  const Trajectory est = timeline(0.05, 10.0, 50);  // always 50 ms from the ground truth
  try {
    associate(est, gt);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "no estimated pose has a ground-truth pose within 0.020000 s")) << e.what();
    EXPECT_TRUE(contains(e.what(), "the closest is 0.050000 s away")) << e.what();
  }
  const Trajectory two = timeline(9.7, 5.0, 5);  // 9.7, 9.9 match; 10.1 .. 10.5 are past the end
  try {
    associate(two, gt);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "only 2 pose(s) pair up")) << e.what();
    EXPECT_TRUE(contains(e.what(), "at least 3 are needed")) << e.what();
  }
  EXPECT_THROW(associate(Trajectory{}, gt), InputError);
}

// 20 Hz camera timestamps of the real sequence against its 200 Hz ground truth. The ground truth
// starts at 1403715274.302 s, so it covers the last 74 of the 95 frames.
TEST(AssociationRealData, EurocCameraStampsPairWithTheGroundTruth) {
  const Trajectory gt = read_trajectory(eval_testing::kEuroc / "groundtruth_tum.txt");
  const EurocReader camera(eval_testing::kEuroc);
  Trajectory est;
  for (const std::int64_t ns : camera.timestamps_ns()) est.poses.push_back({seconds_from_nanoseconds(ns), SE3()});
  ASSERT_EQ(est.size(), 95u);
  const Association a = associate(est, gt);
  EXPECT_EQ(a.pairs.size(), 74u);
  EXPECT_EQ(a.pairs.front().estimate_index, 21u);
  EXPECT_EQ(a.pairs.back().estimate_index, 94u);
  EXPECT_LT(a.max_abs_dt_s, 1e-5);  // the two clocks agree to microseconds
  EXPECT_EQ(a.unmatched_inside_overlap, 0u);
  for (std::size_t k = 1; k < a.pairs.size(); ++k)
    EXPECT_EQ(a.pairs[k].ground_truth_index - a.pairs[k - 1].ground_truth_index, 10u);  // every tenth GT pose
}

}  // namespace
}  // namespace nirslam
