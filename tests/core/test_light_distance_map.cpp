// The lamp distances the pipeline hands the photometric calibration (issue 8): points projected
// through a pose, a patch takes the median distance of the points near it (one side of a depth
// edge, not a blend), none where no point is near.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/pipeline/light_distance_map.hpp"

namespace nirslam {
namespace {

PinholeCamera camera_640() { return PinholeCamera(640, 480, Eigen::Vector4d(500.0, 500.0, 320.0, 240.0)); }

// Points on the plane z = depth (camera frame) on a regular pixel grid with `step` pixels.
std::vector<Eigen::Vector3d> plane_points(const CameraModel& camera, double depth, int step, int x0 = 0, int x1 = 640) {
  std::vector<Eigen::Vector3d> points;
  for (int y = step / 2; y < camera.height(); y += step)
    for (int x = x0 + step / 2; x < x1; x += step)
      points.push_back(depth * *camera.unproject(Eigen::Vector2d(x, y)));
  return points;
}

TEST(LightDistanceMap, DistanceFromTheLampNotFromTheCamera) {
  const PinholeCamera camera = camera_640();
  LightDistanceMap map(camera);
  const Eigen::Vector3d light(0.05, -0.02, 0.0);
  map.build(plane_points(camera, 2.0, 10), SE3::identity(), light);
  EXPECT_EQ(map.projected_points(), 64u * 48u);
  for (const Eigen::Vector2d& pixel : {Eigen::Vector2d(320.0, 240.0), Eigen::Vector2d(33.0, 451.0), Eigen::Vector2d(600.5, 20.5)}) {
    const auto d = map.light_distance(pixel);
    ASSERT_TRUE(d) << pixel.transpose();
    const Eigen::Vector3d surface = 2.0 * *camera.unproject(pixel);
    // The median over neighbours up to 20 px away (one-sided at the border): within 2 %.
    EXPECT_NEAR(*d, (surface - light).norm(), 0.02 * (surface - light).norm()) << pixel.transpose();
  }
}

TEST(LightDistanceMap, PoseMovesThePoints) {
  const PinholeCamera camera = camera_640();
  LightDistanceMap map(camera);
  // The points are in the world; the camera stepped 0.5 towards them.
  const SE3 T_world_cam(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 0.5));
  map.build(plane_points(camera, 3.0, 6), T_world_cam, Eigen::Vector3d::Zero());
  const auto d = map.light_distance(Eigen::Vector2d(320.0, 240.0));
  ASSERT_TRUE(d);
  EXPECT_NEAR(*d, 2.5, 0.01);
}

TEST(LightDistanceMap, NoDistanceWhereNoPointIsNear) {
  const PinholeCamera camera = camera_640();
  LightDistanceMap map(camera);
  EXPECT_FALSE(map.light_distance(Eigen::Vector2d(320.0, 240.0))) << "empty map";
  map.build(plane_points(camera, 2.0, 10, 0, 320), SE3::identity(), Eigen::Vector3d::Zero());
  EXPECT_TRUE(map.light_distance(Eigen::Vector2d(100.0, 240.0)));
  EXPECT_FALSE(map.light_distance(Eigen::Vector2d(500.0, 240.0))) << "right half has no points";
  EXPECT_FALSE(map.light_distance(Eigen::Vector2d(-5.0, 240.0))) << "outside the image";
  map.clear();
  EXPECT_TRUE(map.empty());
  EXPECT_FALSE(map.light_distance(Eigen::Vector2d(100.0, 240.0)));
}

TEST(LightDistanceMap, AtADepthEdgeOneSideWinsNotABlend) {
  const PinholeCamera camera = camera_640();
  LightDistanceMap map(camera);
  // A near box (left half, 1 m) in front of a far wall (right half, 3 m).
  std::vector<Eigen::Vector3d> points = plane_points(camera, 1.0, 6, 0, 320);
  const std::vector<Eigen::Vector3d> far = plane_points(camera, 3.0, 6, 320, 640);
  points.insert(points.end(), far.begin(), far.end());
  map.build(points, SE3::identity(), Eigen::Vector3d::Zero());
  const auto near_side = map.light_distance(Eigen::Vector2d(200.0, 240.0));
  const auto far_side = map.light_distance(Eigen::Vector2d(450.0, 240.0));
  ASSERT_TRUE(near_side && far_side);
  EXPECT_NEAR(*near_side, 1.0 * (*camera.unproject(Eigen::Vector2d(200.0, 240.0))).norm(), 0.01);
  EXPECT_NEAR(*far_side, 3.0 * (*camera.unproject(Eigen::Vector2d(450.0, 240.0))).norm(), 0.03);
  // Just left of the edge most neighbours are on the box: its distance, not a mean of both.
  const auto edge = map.light_distance(Eigen::Vector2d(312.0, 240.0));
  ASSERT_TRUE(edge);
  EXPECT_LT(*edge, 1.05);
}

TEST(LightDistanceMap, PointsBehindOrOutsideAreLeftOut) {
  const PinholeCamera camera = camera_640();
  LightDistanceMap map(camera);
  const std::vector<Eigen::Vector3d> points{{0.0, 0.0, -2.0}, {100.0, 0.0, 1.0}, {0.0, 0.0, 2.0}};
  map.build(points, SE3::identity(), Eigen::Vector3d::Zero());
  EXPECT_EQ(map.projected_points(), 1u);
}

}  // namespace
}  // namespace nirslam

namespace nirslam {
namespace {

TEST(LightDistanceMap, CosineOfTheLightOnAPlane) {
  const PinholeCamera camera(640, 480, Eigen::Vector4d(500.0, 500.0, 320.0, 240.0));
  LightDistanceMap map(camera);
  // A floor 1.5 m below the camera (y down), seen ahead: the light grazes it far away.
  std::vector<Eigen::Vector3d> points;
  for (int y = 250; y < 480; y += 5)
    for (int x = 3; x < 640; x += 5) {
      const Eigen::Vector3d ray = *camera.unproject(Eigen::Vector2d(x, y));
      points.push_back(ray * (1.5 / ray.y()));
    }
  map.build(points, SE3::identity(), Eigen::Vector3d::Zero());
  for (const Eigen::Vector2d& pixel : {Eigen::Vector2d(320.0, 300.0), Eigen::Vector2d(320.0, 450.0), Eigen::Vector2d(100.0, 400.0)}) {
    const auto geometry = map.light_geometry(pixel);
    ASSERT_TRUE(geometry) << pixel.transpose();
    const Eigen::Vector3d ray = *camera.unproject(pixel);
    const Eigen::Vector3d surface = ray * (1.5 / ray.y());
    const double cosine = 1.5 / surface.norm();  // normal (0, -1, 0) towards the lamp at the origin
    if (cosine < 0.2) {
      EXPECT_FALSE(geometry->cosine) << "grazing: left out";
      continue;
    }
    ASSERT_TRUE(geometry->cosine) << pixel.transpose();
    EXPECT_NEAR(*geometry->cosine, cosine, 0.02) << pixel.transpose();
    ASSERT_TRUE(geometry->normal_cam);
    EXPECT_LT((*geometry->normal_cam - Eigen::Vector3d(0.0, -1.0, 0.0)).norm(), 0.02) << "facing the lamp";
  }
  // A scattered cloud fits no plane: a distance, no cosine.
  std::vector<Eigen::Vector3d> cloud;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector2d pixel(300.0 + (i * 37) % 40, 220.0 + (i * 53) % 40);
    cloud.push_back((1.0 + 0.5 * ((i * 7919) % 13) / 13.0) * *camera.unproject(pixel));
  }
  map.build(cloud, SE3::identity(), Eigen::Vector3d::Zero());
  const auto geometry = map.light_geometry(Eigen::Vector2d(320.0, 240.0));
  ASSERT_TRUE(geometry);
  EXPECT_FALSE(geometry->cosine);
}

}  // namespace
}  // namespace nirslam
