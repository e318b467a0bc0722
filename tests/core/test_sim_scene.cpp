// Simulator scenes and renderer: geometry, culling against brute force, the radiometry of a flat
// wall, band-limited textures.

#include <cmath>
#include <memory>
#include <numbers>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/sim/renderer.hpp"
#include "nirslam/sim/scene.hpp"
#include "nirslam/sim/texture.hpp"
#include "nirslam/sim/trajectory.hpp"

namespace nirslam::sim {
namespace {

constexpr SceneKind kScenes[] = {SceneKind::Room, SceneKind::Outdoor, SceneKind::Parking, SceneKind::Tunnel};

std::shared_ptr<const CameraModel> small_camera(int w = 64, int h = 48) {
  return std::make_shared<PinholeCamera>(w, h, Eigen::Vector4d(0.65 * w, 0.65 * w, 0.5 * (w - 1), 0.5 * (h - 1)));
}

// A wall facing the camera at distance d along world +x, camera at the origin looking along +x.
std::shared_ptr<const Scene> wall_scene(double d) {
  auto scene = std::make_shared<Scene>();
  Primitive wall;
  wall.shape = Shape::Box;
  wall.lo = Eigen::Vector3f(static_cast<float>(d), -50.0f, -50.0f);
  wall.hi = Eigen::Vector3f(static_cast<float>(d) + 0.2f, 50.0f, 50.0f);
  wall.side = wall.top = wall.bottom = Material::Concrete;
  scene->primitives.push_back(wall);
  return scene;
}

SE3 looking_along_x() { return look_at({0, 0, 0}, {1, 0, 0}, {0, 0, -1}); }

TEST(SimScene, NamesRoundTrip) {
  for (const SceneKind k : kScenes) EXPECT_EQ(parse_scene_kind(to_string(k)), k);
  EXPECT_EQ(parse_scene_kind("Underground"), SceneKind::Parking);
  EXPECT_FALSE(parse_scene_kind("moon"));
}

TEST(SimScene, ScenesAreDeterministicAndEnclosingPrimitivesComeFirst) {
  for (const SceneKind k : kScenes) {
    const Scene a = make_scene(k, 7), b = make_scene(k, 7);
    ASSERT_EQ(a.primitives.size(), b.primitives.size()) << to_string(k);
    ASSERT_GT(a.primitives.size(), 10u) << to_string(k);
    for (std::size_t i = 0; i < a.primitives.size(); ++i) {
      EXPECT_EQ(a.primitives[i].lo, b.primitives[i].lo);
      EXPECT_EQ(a.primitives[i].seed, b.primitives[i].seed);
    }
    bool bounded_seen = false;
    for (const Primitive& p : a.primitives) {
      if (!p.unbounded()) bounded_seen = true;
      else EXPECT_FALSE(bounded_seen) << "unbounded primitive after bounded ones in " << to_string(k);
    }
    for (const PrimitiveGroup& g : a.groups) {
      for (int i = 0; i < g.count; ++i) {
        Eigen::Vector3f lo, hi;
        a.primitives[static_cast<std::size_t>(g.first + i)].bounds(lo, hi);
        EXPECT_TRUE((lo.array() >= g.lo.array() - 1e-5f).all() && (hi.array() <= g.hi.array() + 1e-5f).all());
      }
    }
  }
}

TEST(SimRenderer, TileCullingFindsTheSameSurfacesAsBruteForce) {
  for (const SceneKind k : kScenes) {
    auto scene = std::make_shared<const Scene>(make_scene(k, 3));
    const auto camera = small_camera();
    const Renderer renderer(scene, camera, 2);
    const Trajectory trajectory = make_trajectory(k, MotionKind::Handheld, 3);
    for (const double t : {0.0, 7.3, 21.0}) {
      const SE3 pose = trajectory.pose(t);
      cv::Mat radiance, depth;
      renderer.render(std::span<const SE3>(&pose, 1), Lighting{}, radiance, &depth);
      int mismatches = 0;
      for (int y = 0; y < camera->height(); ++y)
        for (int x = 0; x < camera->width(); ++x) {
          const Eigen::Vector3d ray = *camera->unproject(Eigen::Vector2d(x, y));
          const auto hit = cast_ray(*scene, pose.translation(), pose.rotation_matrix() * ray);
          const double z = hit ? (pose.inverse() * hit->point).z() : 0.0;
          if (std::abs(z - depth.at<float>(y, x)) > 1e-3 * std::max(1.0, z)) ++mismatches;
        }
      EXPECT_EQ(mismatches, 0) << to_string(k) << " at t=" << t;
    }
  }
}

// With one ray a pixel the renderer traces four neighbouring pixels of a row as one packet; each
// pixel must still see its own surface, as the one-ray path (render_pixel, no culling) does. The
// texture footprint is fixed and the floor matte so that both paths shade alike. The packet's
// and the single ray's arithmetic differ in the last bits (the ground plane divides by the
// direction in one and multiplies by its inverse in the other): up to 0.2 % at a few pixels, the
// same before packets spanned pixels, hence 1 %. Lanes handed the wrong pixels' hits (the
// pixel two to the left) put about 530 of the 2480 pixels outside it.
TEST(SimRenderer, RowPacketsGiveEachPixelItsOwnSurface) {
  ShadingOptions shading;
  shading.texture_footprint_m = 0.01;
  shading.glossy_floor = false;
  Lighting lighting;
  lighting.illuminator.power_w = 50.0;
  lighting.ambient_irradiance = 0.2;
  lighting.sky_radiance = 0.05;
  for (const SceneKind k : kScenes) {
    auto scene = std::make_shared<const Scene>(make_scene(k, 3));
    const auto camera = small_camera(62, 40);  // rows of 62: the last packet of each row holds two pixels
    const Renderer renderer(scene, camera, 1, shading);
    const Trajectory trajectory = make_trajectory(k, MotionKind::Handheld, 3);
    for (const double t : {0.0, 9.1}) {
      const SE3 pose = trajectory.pose(t);
      cv::Mat radiance;
      renderer.render(std::span<const SE3>(&pose, 1), lighting, radiance);
      int mismatches = 0;
      for (int y = 0; y < camera->height(); ++y)
        for (int x = 0; x < camera->width(); ++x) {
          const double expected = renderer.render_pixel(pose, lighting, Eigen::Vector2d(x, y)).radiance;
          if (std::abs(radiance.at<float>(y, x) - expected) > 0.01 * std::max(expected, 1e-3)) ++mismatches;
        }
      EXPECT_EQ(mismatches, 0) << to_string(k) << " at t=" << t;
    }
  }
}

TEST(SimRenderer, FlatWallRadianceFollowsTheInverseSquareLaw) {
  for (const double d : {1.0, 2.0, 4.0}) {
    const Renderer renderer(wall_scene(d), small_camera(), 2);
    Lighting lighting;
    lighting.illuminator.offset_cam.setZero();
    lighting.illuminator.power_w = 50.0;
    const Renderer::PixelSample s = renderer.render_pixel(looking_along_x(), lighting, {31.5, 23.5});
    ASSERT_TRUE(s.hit);
    EXPECT_NEAR(s.hit->t, d, 1e-5);
    const double expected_irradiance = lighting.illuminator.axial_intensity() * lighting.illuminator.beam(0.0) / (d * d);
    EXPECT_NEAR(s.irradiance, expected_irradiance, 1e-5 * expected_irradiance);
    EXPECT_NEAR(s.radiance, s.albedo / std::numbers::pi * expected_irradiance, 1e-5 * expected_irradiance);
    EXPECT_GT(s.albedo, 0.05);
    EXPECT_LT(s.albedo, 0.9);
  }
  // The axial intensity: efficiency * P * (m + 1) / (2 pi), B(half angle) = 1/2.
  Illuminator light;
  EXPECT_NEAR(light.beam(light.half_angle_deg * std::numbers::pi / 180.0), 0.5, 1e-12);
  EXPECT_NEAR(light.axial_intensity(), 0.35 * 50.0 * (light.beam_exponent() + 1.0) / (2.0 * std::numbers::pi), 1e-12);
}

TEST(SimRenderer, RadianceDoublesWithPowerWithoutAmbientLight) {
  auto scene = std::make_shared<const Scene>(make_scene(SceneKind::Tunnel, 1));
  const Renderer renderer(scene, small_camera(), 2);
  const SE3 pose = make_trajectory(SceneKind::Tunnel, MotionKind::Vehicle, 1).pose(2.0);
  Lighting low, high;
  low.illuminator.power_w = 40.0;
  high.illuminator.power_w = 80.0;
  cv::Mat a, b;
  renderer.render(std::span<const SE3>(&pose, 1), low, a);
  renderer.render(std::span<const SE3>(&pose, 1), high, b);
  EXPECT_LT(cv::norm(b, 2.0 * a, cv::NORM_INF), 1e-5 * cv::norm(b, cv::NORM_INF));
  EXPECT_GT(cv::mean(a)[0], 0.0);
}

TEST(SimRenderer, CentreOfTheImageIsBrighterThanTheRimOnAFlatWall) {
  const Renderer renderer(wall_scene(2.0), small_camera(), 2);
  const SE3 pose = looking_along_x();
  cv::Mat radiance;
  renderer.render(std::span<const SE3>(&pose, 1), Lighting{}, radiance);
  const double centre = cv::mean(radiance(cv::Rect(24, 16, 16, 16)))[0];
  const double corner = cv::mean(radiance(cv::Rect(0, 0, 8, 8)))[0];
  EXPECT_GT(centre, 1.5 * corner);  // beam, cos(theta) and 1/d^2 all fall off
}

TEST(SimTexture, DetailFadesToItsMeanBeyondThePixelFootprint) {
  // Sample a textured wall finely: with a large footprint the pattern is smooth (no aliasing),
  // with a small one it has detail; both have about the same mean.
  for (const Material m : {Material::Concrete, Material::Bookshelf, Material::Brick, Material::TunnelLining}) {
    double mean_sharp = 0.0, mean_blurred = 0.0, var_sharp = 0.0, var_blurred = 0.0;
    const int n = 4000;
    for (int i = 0; i < n; ++i) {
      const float u = 0.0137f * static_cast<float>(i), v = 1.2f + 0.0071f * static_cast<float>(i % 97);
      const double a = material_albedo(m, u, v, 0.0005f, 5u), b = material_albedo(m, u, v, 0.5f, 5u);
      EXPECT_GE(a, 0.0);
      EXPECT_LE(a, 1.0);
      mean_sharp += a;
      mean_blurred += b;
      var_sharp += a * a;
      var_blurred += b * b;
    }
    mean_sharp /= n;
    mean_blurred /= n;
    var_sharp = var_sharp / n - mean_sharp * mean_sharp;
    var_blurred = var_blurred / n - mean_blurred * mean_blurred;
    EXPECT_NEAR(mean_sharp, mean_blurred, 0.1) << to_string(m);
    EXPECT_LT(var_blurred, var_sharp) << to_string(m);
  }
  EXPECT_GE(value_noise(0.3f, 0.7f), 0.0f);
  EXPECT_LE(value_noise(0.3f, 0.7f), 1.0f);
}

}  // namespace
}  // namespace nirslam::sim
