// The geometric start for the direct initialiser (geometric_start.hpp): the reprojection
// Jacobians against numeric differentiation, the bundle adjustment on a synthetic problem with a
// known answer, and the camera-centre direction over the first 20 frames of the simulated
// hand-held room under the lamp, where the direct initialiser alone hands over a direction
// 10-70 degrees off (README, "Odometry benchmark").

#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/odometry/direct_odometry.hpp"
#include "nirslam/odometry/geometric_start.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam::odometry {
namespace {

const LevelCamera kGeometricCamera{417.0, 417.0, 319.5, 239.5, 640, 480};

double direction_error_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

Eigen::Vector3d camera_centre_of(const SE3& T_frame_first) {
  return -(T_frame_first.rotation_matrix().transpose() * T_frame_first.translation());
}

// A simulated frame as the odometry takes it (grey 0..255 as float).
OdometryFrame odometry_frame_of(const Frame& f) {
  OdometryFrame frame;
  frame.frame_index = f.index;
  frame.timestamp_s = f.timestamp_s;
  const double scale = f.image.depth() == CV_16U ? 255.0 / f.max_value() : 1.0;
  f.image.convertTo(frame.image, CV_32F, scale);
  return frame;
}

// The bench's hand-held room under the lamp at `power_w`, 640x480 without supersampling.
SimulatorOptions hand_held_room(double power_w, std::int64_t frames) {
  SimulatorOptions o;
  o.scene = sim::SceneKind::Room;
  o.powers_w = {power_w};
  o.frames = frames;
  o.supersampling = 1;
  return o;
}

TEST(GeometricStart, ReprojectionJacobiansMatchNumericDifferentiation) {
  const SE3 T = SE3::exp((Vector6d() << 0.1, -0.05, 0.2, 0.03, -0.02, 0.05).finished());
  const Eigen::Vector3d X(0.4, -0.3, 2.5);
  const Eigen::Vector2d pixel(300.0, 250.0);
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 6> d_pose;
  Eigen::Matrix<double, 2, 3> d_point;
  ASSERT_TRUE(reprojection_jacobians(kGeometricCamera, T, X, pixel, r, d_pose, d_point));
  const double h = 1e-6;
  for (int k = 0; k < 6; ++k) {
    Vector6d xi = Vector6d::Zero();
    xi[k] = h;
    Eigen::Vector2d rp, rm;
    Eigen::Matrix<double, 2, 6> unused_pose;
    Eigen::Matrix<double, 2, 3> unused_point;
    ASSERT_TRUE(reprojection_jacobians(kGeometricCamera, SE3::exp(xi) * T, X, pixel, rp, unused_pose, unused_point));
    ASSERT_TRUE(reprojection_jacobians(kGeometricCamera, SE3::exp(-xi) * T, X, pixel, rm, unused_pose, unused_point));
    const Eigen::Vector2d numeric = (rp - rm) / (2.0 * h);
    EXPECT_NEAR((numeric - d_pose.col(k)).norm(), 0.0, 1e-4 * (1.0 + numeric.norm())) << "pose column " << k;
  }
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d dX = Eigen::Vector3d::Zero();
    dX[k] = h;
    Eigen::Vector2d rp, rm;
    Eigen::Matrix<double, 2, 6> unused_pose;
    Eigen::Matrix<double, 2, 3> unused_point;
    ASSERT_TRUE(reprojection_jacobians(kGeometricCamera, T, X + dX, pixel, rp, unused_pose, unused_point));
    ASSERT_TRUE(reprojection_jacobians(kGeometricCamera, T, X - dX, pixel, rm, unused_pose, unused_point));
    const Eigen::Vector2d numeric = (rp - rm) / (2.0 * h);
    EXPECT_NEAR((numeric - d_point.col(k)).norm(), 0.0, 1e-4 * (1.0 + numeric.norm())) << "point column " << k;
  }
}

TEST(GeometricStart, BundleAdjustmentRecoversTheMotionFromAPerturbedStart) {
  // 20 frames of a small walking motion (sideways, forwards, a little vertical bob and turning)
  // towards points 2-5 m away, observed with 0.3 px noise and 5 % gross outliers; the start is
  // 12 degrees off in every frame's translation direction, 1 degree in rotation, and the points
  // 10 % off in depth.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.3);
  const int frames = 21;
  std::vector<SE3> truth(frames);
  for (int k = 0; k < frames; ++k) {
    const double s = k / 20.0;
    const Eigen::Vector3d c(0.12 * s, 0.02 * std::sin(6.0 * s), 0.25 * s);
    const Eigen::Matrix3d R = so3_exp(Eigen::Vector3d(0.01 * std::sin(5.0 * s), 0.04 * s, 0.0));
    truth[static_cast<std::size_t>(k)] = SE3(R, -(R * c));
  }
  std::vector<Eigen::Vector3d> points_truth;
  for (int i = 0; i < 150; ++i) {
    const double z = 3.5 + 1.5 * uniform(rng);
    points_truth.emplace_back(0.6 * z * uniform(rng), 0.45 * z * uniform(rng), z);
  }
  std::vector<BundleObservation> observations;
  for (int i = 0; i < static_cast<int>(points_truth.size()); ++i)
    for (int k = 0; k < frames; ++k) {
      Eigen::Vector2d pixel = kGeometricCamera.project(truth[static_cast<std::size_t>(k)] * points_truth[static_cast<std::size_t>(i)]);
      pixel += Eigen::Vector2d(noise(rng), noise(rng));
      if (k > 0 && (i * 31 + k * 7) % 20 == 0) pixel += Eigen::Vector2d(15.0, -10.0);  // a tracking slip
      observations.push_back({k, i, pixel});
    }
  std::vector<SE3> poses(frames);
  for (int k = 1; k < frames; ++k) {
    const SE3& T = truth[static_cast<std::size_t>(k)];
    const Eigen::Vector3d c = camera_centre_of(T);
    const Eigen::Vector3d c_off = Eigen::AngleAxisd(12.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()) * c;
    const Eigen::Matrix3d R = so3_exp(Eigen::Vector3d(0.0, 0.0, M_PI / 180.0)) * T.rotation_matrix();
    poses[static_cast<std::size_t>(k)] = SE3(R, -(R * c_off));
  }
  std::vector<Eigen::Vector3d> points = points_truth;
  for (auto& p : points) p *= 1.0 + 0.1 * uniform(rng);
  for (int k = 10; k < frames; k += 5)
    ASSERT_GT(direction_error_deg(camera_centre_of(poses[static_cast<std::size_t>(k)]), camera_centre_of(truth[static_cast<std::size_t>(k)])), 10.0);

  const BundleResult result = adjust_bundle(kGeometricCamera, poses, points, observations, 1.0, 50);
  EXPECT_LT(result.rms_px, 0.45);  // the noise's 0.3 px per axis is 0.42 px per observation
  EXPECT_GT(result.inlier_observations, static_cast<int>(0.9 * static_cast<double>(observations.size())));
  for (int k = 8; k < frames; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    EXPECT_LT(direction_error_deg(camera_centre_of(poses[kk]), camera_centre_of(truth[kk])), 1.0) << "frame " << k;
    EXPECT_LT(so3_log(poses[kk].rotation_matrix() * truth[kk].rotation_matrix().transpose()).norm() * 180.0 / M_PI, 0.1)
        << "frame " << k;
  }
}

TEST(GeometricStart, DirectionOfTheHandHeldRoomUnderTheLamp) {
  // The bench's room at 100 W from its first frame: the auto exposure ramps down over the first
  // frames (plain KLT loses most tracks there; these are gain-robust). The direct initialiser
  // alone hands this start over 10-70 degrees off.
  const SimulatorOptions o = hand_held_room(100.0, 21);
  Simulator simulator(o);
  const auto camera = make_sim_camera(o);
  const LevelCamera base{camera->intrinsics()[0], camera->intrinsics()[1], camera->intrinsics()[2],
                         camera->intrinsics()[3], o.width, o.height};
  GeometricStart start(base, GeometricStartOptions{});
  std::vector<SE3> T_world_cam;
  while (auto f = simulator.next()) {
    cv::Mat image;
    const double scale = f->frame.image.depth() == CV_16U ? 255.0 / f->frame.max_value() : 1.0;
    f->frame.image.convertTo(image, CV_32F, scale);
    if (T_world_cam.empty())
      start.set_first(image);
    else
      start.add_frame(image);
    T_world_cam.push_back(f->T_world_cam);
  }
  ASSERT_TRUE(start.complete());
  const GeometricStartResult result = start.solve();
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_GE(result.inliers, 50);
  EXPECT_LT(result.rms_px, 1.0);
  ASSERT_EQ(result.T_frame_first.size(), T_world_cam.size());
  for (std::size_t k = 8; k < T_world_cam.size(); ++k) {
    const Eigen::Vector3d c_true = T_world_cam[0].inverse() * T_world_cam[k].translation();
    EXPECT_LT(direction_error_deg(camera_centre_of(result.T_frame_first[k]), c_true), 4.0) << "frame " << k;
  }
}

// The odometry with the geometric start: the frames are held back until the start has its 20,
// then replayed; every frame gets a pose, and the camera centre's direction from the first frame
// follows the truth, where without it the hand-over's is 10-70 degrees off on such starts.
TEST(GeometricStart, OdometryHoldsTheFramesBackAndReplaysThem) {
  const SimulatorOptions o = hand_held_room(20.0, 40);
  Simulator simulator(o);
  OdometryOptions options;
  options.init_geometric_frames = 20;
  const auto camera = make_sim_camera(o);
  DirectOdometry odometry(PinholeCamera(camera->width(), camera->height(), camera->intrinsics()), options);
  std::vector<SE3> T_world_cam;
  std::vector<OdometryResult> results;
  while (auto f = simulator.next()) {
    results.push_back(odometry.process(odometry_frame_of(f->frame)));
    T_world_cam.push_back(f->T_world_cam);
  }
  for (std::size_t k = 0; k < 20; ++k) {
    EXPECT_EQ(results[k].status, TrackingStatus::Initialising) << "frame " << k;
    EXPECT_NE(results[k].message.find("geometric start, frame"), std::string::npos) << results[k].message;
  }
  // Frame 20 replays the held frames: the initialiser hands over among them.
  EXPECT_EQ(results[20].status, TrackingStatus::Tracking) << results[20].message;
  EXPECT_NE(results[20].message.find("initialised with"), std::string::npos) << results[20].message;
  EXPECT_NE(results[20].message.find("geometric start: "), std::string::npos) << results[20].message;
  const std::vector<PoseStamped> trajectory = odometry.trajectory();
  ASSERT_EQ(trajectory.size(), T_world_cam.size());
  const SE3 T_first_world = trajectory[0].T_world_cam.inverse();
  for (std::size_t k = 10; k < trajectory.size(); ++k) {
    const Eigen::Vector3d c = T_first_world * trajectory[k].T_world_cam.translation();
    const Eigen::Vector3d c_true = T_world_cam[0].inverse() * T_world_cam[k].translation();
    EXPECT_LT(direction_error_deg(c, c_true), 5.0) << "frame " << k;
  }
}

// The largest angle between the camera centre's direction from the first frame the odometry
// gives and the truth's, over frames 10 on, with the odometry started at frame `skip` of the room
// at 50 W rendered as `bench` renders it (the 12-run start-offset set's starts from frame 30).
double room_start_direction_error_deg(std::int64_t skip, bool hold_keyframes) {
  SimulatorOptions o = hand_held_room(50.0, skip + 40);
  o.supersampling = 2;
  Simulator simulator(o);
  OdometryOptions options;
  options.init_geometric_frames = 20;
  options.init_hold_geometric_pose = hold_keyframes;
  const auto camera = make_sim_camera(hand_held_room(50.0, 1));
  DirectOdometry odometry(PinholeCamera(camera->width(), camera->height(), camera->intrinsics()), options);
  std::vector<SE3> T_world_cam;
  while (auto f = simulator.next()) {
    if (f->frame.index < skip) continue;
    odometry.process(odometry_frame_of(f->frame));
    T_world_cam.push_back(f->T_world_cam);
  }
  const std::vector<PoseStamped> trajectory = odometry.trajectory();
  EXPECT_EQ(trajectory.size(), T_world_cam.size());
  const SE3 T_first_world = trajectory[0].T_world_cam.inverse();
  double worst = 0.0;
  for (std::size_t k = 10; k < trajectory.size() && k < T_world_cam.size(); ++k) {
    const Eigen::Vector3d c = T_first_world * trajectory[k].T_world_cam.translation();
    const Eigen::Vector3d c_true = T_world_cam[0].inverse() * T_world_cam[k].translation();
    worst = std::max(worst, direction_error_deg(c, c_true));
  }
  return worst;
}

// The keyframes among the held frames held at the geometric start's poses
// (OdometryOptions::init_hold_geometric_pose): with two keyframes the direction of travel is
// weakly determined, and without the hold the window's first optimisations turned it by about
// 20 degrees on this start (the bench's render, 2x2 supersampling; the geometric start itself
// had it within 0.1 degree). Measured: held 4.9 degrees at worst from frame 10 on, free 24.9
// (room_start_direction_error_deg(30, false)).
TEST(GeometricStart, HeldKeyframesKeepTheDirectionOfARoomStartFromFrame30) {
  const double held = room_start_direction_error_deg(30, true);
  std::cout << "room 50 W from frame 30, worst direction error from frame 10 with the keyframes held: " << held
            << " deg\n";
  EXPECT_LT(held, 8.0);
}

// Two textured walls facing the camera, 2 m away left of centre and 4 m away right of it (depth
// variety: over one plane a sideways step and a pan make nearly the same flow), seen by a camera
// that pans and moves `baseline_m` along (1, 0, 1) / sqrt(2) over the 20 frames.
GeometricStartResult two_wall_start(double baseline_m) {
  cv::Mat texture(1200, 1600, CV_32FC1);
  cv::randu(texture, 0.0, 255.0);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 2.0);
  const LevelCamera& cam = kGeometricCamera;
  const Eigen::Vector3d direction = Eigen::Vector3d(1.0, 0.0, 1.0).normalized();
  auto view = [&](int k) {
    cv::Mat image(cam.height, cam.width, CV_32FC1);
    const Eigen::Matrix3d R = so3_exp(Eigen::Vector3d(0.0, 0.002 * k, 0.0));
    const Eigen::Vector3d c = direction * (baseline_m * k / 20.0);
    for (int v = 0; v < cam.height; ++v)
      for (int u = 0; u < cam.width; ++u) {
        const Eigen::Vector3d ray = R.transpose() * cam.unproject(Eigen::Vector2d(u, v));
        Eigen::Vector3d hit = c + ray * ((2.0 - c.z()) / ray.z());
        if (hit.x() >= 0.0) hit = c + ray * ((4.0 - c.z()) / ray.z());
        const double x = hit.x() * 250.0 + 800.0, y = hit.y() * 250.0 + 600.0;
        image.at<float>(v, u) = x >= 0 && y >= 0 && x < 1599 && y < 1199
                                    ? texture.at<float>(static_cast<int>(y), static_cast<int>(x))
                                    : 0.0f;
      }
    return image;
  };
  GeometricStart start(cam, GeometricStartOptions{});
  start.set_first(view(0));
  for (int k = 1; k <= 20; ++k) start.add_frame(view(k));
  return start.solve();
}

TEST(GeometricStart, TooLittleTranslationLeavesTheDirectionUndetermined) {
  // A rotation alone fits no essential matrix well; 1 cm adds about 1 px of flow: too little to
  // tell the direction, so the start must say it has none.
  for (const double baseline_m : {0.0, 0.01}) {
    const GeometricStartResult result = two_wall_start(baseline_m);
    EXPECT_FALSE(result.ok) << baseline_m;
    EXPECT_TRUE(result.reason.find("parallax") != std::string::npos || result.reason.find("inliers") != std::string::npos)
        << result.reason;
  }
  // 20 cm: determined.
  const GeometricStartResult moving = two_wall_start(0.2);
  ASSERT_TRUE(moving.ok) << moving.reason;
  EXPECT_GT(moving.parallax_px, 8.0);
  EXPECT_LT(direction_error_deg(camera_centre_of(moving.T_frame_first.back()), Eigen::Vector3d(1.0, 0.0, 1.0)), 2.0);
}

TEST(GeometricStart, TooFewTracksSaysSo) {
  GeometricStart start(kGeometricCamera, GeometricStartOptions{});
  const cv::Mat flat(480, 640, CV_32FC1, cv::Scalar(100.0f));
  start.set_first(flat);
  for (int k = 0; k < 20; ++k) start.add_frame(flat);
  const GeometricStartResult result = start.solve();
  EXPECT_FALSE(result.ok);
  EXPECT_NE(result.reason.find("tracks reach frame 20"), std::string::npos) << result.reason;
}

}  // namespace
}  // namespace nirslam::odometry
