// Simulator trajectories: clear of the geometry, smooth, looping, and the paper's capture rule.

#include <cmath>

#include <gtest/gtest.h>

#include "nirslam/sim/scene.hpp"
#include "nirslam/sim/trajectory.hpp"

namespace nirslam::sim {
namespace {

constexpr SceneKind kEveryScene[] = {SceneKind::Room, SceneKind::Outdoor, SceneKind::Parking, SceneKind::Tunnel};
constexpr MotionKind kMotions[] = {MotionKind::Handheld, MotionKind::Vehicle, MotionKind::Robot, MotionKind::Tripod};

TEST(SimTrajectory, NamesRoundTrip) {
  for (const MotionKind m : kMotions) EXPECT_EQ(parse_motion_kind(to_string(m)), m);
  EXPECT_EQ(parse_motion_kind("Hand-held"), MotionKind::Handheld);
  EXPECT_FALSE(parse_motion_kind("drone"));
  EXPECT_EQ(parse_motion_kind("still"), MotionKind::Tripod);
}

// A tripod holds the handheld path's first view, clear of the scene, for good (power sweeps).
TEST(SimTrajectory, TripodStandsStillWhereTheHandheldPathStarts) {
  for (const SceneKind k : kEveryScene) {
    const Trajectory tripod = make_trajectory(k, MotionKind::Tripod, 1);
    const Trajectory handheld = make_trajectory(k, MotionKind::Handheld, 1);
    const SE3 first = tripod.pose(0.0);
    for (const double t : {0.5, 7.0, 100.0}) {
      const SE3 later = tripod.pose(t);
      EXPECT_LT((later.translation() - first.translation()).norm(), 1e-12) << to_string(k);
      EXPECT_LT((later.rotation_matrix() - first.rotation_matrix()).norm(), 1e-12) << to_string(k);
    }
    // Within the handheld's sway (1.2 cm) of where it starts.
    EXPECT_LT((first.translation().head<2>() - handheld.position(0.0).head<2>()).norm(), 0.015) << to_string(k);
  }
}

TEST(SimTrajectory, EveryPathKeepsClearOfTheSceneOverAWholeLoop) {
  // 26 directions round the camera; the nearest surface must stay beyond the clearance, and in
  // enclosed scenes every direction must hit something (the camera is inside).
  std::vector<Eigen::Vector3d> directions;
  for (int x = -1; x <= 1; ++x)
    for (int y = -1; y <= 1; ++y)
      for (int z = -1; z <= 1; ++z)
        if (x || y || z) directions.emplace_back(x, y, z);
  for (const SceneKind k : kEveryScene) {
    const Scene scene = make_scene(k, 1);
    for (const MotionKind m : kMotions) {
      const Trajectory trajectory = make_trajectory(k, m, 1);
      double nearest = 1e9;
      for (double t = 0.0; t < trajectory.period(); t += 0.3) {
        const Eigen::Vector3d c = trajectory.pose(t).translation();
        for (const Eigen::Vector3d& d : directions) {
          const auto hit = cast_ray(scene, c, d);
          if (!hit) {
            EXPECT_EQ(k, SceneKind::Outdoor) << "camera outside the " << to_string(k);
            continue;
          }
          nearest = std::min(nearest, hit->t);
        }
      }
      EXPECT_GT(nearest, scene.min_clearance_m - 0.05) << to_string(k) << " " << to_string(m);
    }
  }
}

TEST(SimTrajectory, PathsAreSmoothAndLoop) {
  for (const SceneKind k : kEveryScene) {
    for (const MotionKind m : kMotions) {
      const Trajectory trajectory = make_trajectory(k, m, 2);
      EXPECT_GT(trajectory.loop_length(), 5.0);
      EXPECT_NEAR(trajectory.loop_length() / trajectory.period(), trajectory.speed(), 1e-9);
      // The ground track comes back to where it started after one period.
      const Eigen::Vector3d start = trajectory.position(0.0), end = trajectory.position(trajectory.period());
      EXPECT_LT((start.head<2>() - end.head<2>()).norm(), 0.05) << to_string(k) << " " << to_string(m);
      // Bounded acceleration and angular acceleration: no kinks anywhere.
      const double h = 0.01;
      double max_acc = 0.0, max_ang_acc = 0.0, max_speed = 0.0;
      for (double t = h; t < trajectory.period(); t += 0.05) {
        const SE3 a = trajectory.pose(t - h), b = trajectory.pose(t), c = trajectory.pose(t + h);
        max_acc = std::max(max_acc, ((a.translation() - 2 * b.translation() + c.translation()) / (h * h)).norm());
        max_speed = std::max(max_speed, ((c.translation() - a.translation()) / (2 * h)).norm());
        const Eigen::Vector3d w1 = (a.inverse() * b).log().tail<3>() / h, w2 = (b.inverse() * c).log().tail<3>() / h;
        max_ang_acc = std::max(max_ang_acc, (w2 - w1).norm() / h);
      }
      EXPECT_LT(max_speed, 1.5 * trajectory.speed() + 0.2) << to_string(k) << " " << to_string(m);
      EXPECT_LT(max_acc, 12.0) << to_string(k) << " " << to_string(m);
      EXPECT_LT(max_ang_acc, 40.0) << to_string(k) << " " << to_string(m);
    }
  }
}

TEST(SimTrajectory, CaptureRuleTakesAFrameEveryIntervalOrDistance) {
  const Trajectory trajectory = make_trajectory(SceneKind::Parking, MotionKind::Vehicle, 1);
  const CaptureRule rule{0.1, 0.05};  // 5 cm at 2.5 m/s: about every 20 ms
  const std::vector<double> times = frame_times(trajectory, 50, 30.0, rule);
  ASSERT_EQ(times.size(), 50u);
  EXPECT_EQ(times[0], 0.0);
  for (std::size_t i = 1; i < times.size(); ++i) {
    const double dt = times[i] - times[i - 1];
    EXPECT_GT(dt, 0.0);
    EXPECT_LE(dt, rule.max_interval_s + 1e-9);
    const double moved = (trajectory.position(times[i]) - trajectory.position(times[i - 1])).norm();
    EXPECT_LE(moved, rule.max_distance_m + 0.003);
    EXPECT_GE(moved, 0.8 * rule.max_distance_m);  // at this speed the distance decides
  }
  const std::vector<double> fixed = frame_times(trajectory, 4, 20.0);
  EXPECT_DOUBLE_EQ(fixed[3], 0.15);
}

}  // namespace
}  // namespace nirslam::sim
