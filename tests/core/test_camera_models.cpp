// Camera models: project/unproject inverse to each other over the whole image, analytic
// Jacobians against finite differences, and agreement with OpenCV on the same parameters.

#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "camera_fixtures.hpp"
#include "nirslam/camera/camera_model.hpp"
#include "nirslam/camera/undistorter.hpp"

namespace nirslam {
namespace {

using namespace test_cameras;

std::vector<std::shared_ptr<const CameraModel>> all_models() {
  return {
      std::make_shared<PinholeCamera>(640, 480, Eigen::Vector4d(500.0, 505.0, 319.5, 239.5)),
      std::make_shared<RadTanCamera>(euroc_cam0()),
      // Pincushion with strong tangential terms, to exercise every term of the Jacobian.
      std::make_shared<RadTanCamera>(752, 480, Eigen::Vector4d(458.654, 457.296, 367.215, 248.375),
                                     Eigen::Vector4d(0.12, -0.05, 0.004, -0.003)),
      std::make_shared<FovCamera>(tum_monovo_fov()),
      std::make_shared<EquidistantCamera>(tumvi_fisheye()),
  };
}

// Whether a pixel sees a ray in front of the camera. The wide lenses of TUM monoVO and TUM-VI see
// beyond 90 degrees in their image corners; those pixels have no ray with z = 1.
bool has_forward_ray(const CameraModel& camera, const Eigen::Vector2d& pixel) {
  const double r_d = Eigen::Vector2d((pixel.x() - camera.cx()) / camera.fx(),
                                     (pixel.y() - camera.cy()) / camera.fy())
                         .norm();
  if (const auto* fov = dynamic_cast<const FovCamera*>(&camera))
    return r_d * fov->omega() < std::numbers::pi / 2.0;
  if (const auto* kb = dynamic_cast<const EquidistantCamera*>(&camera))
    return r_d < kb->distort_angle(kb->max_theta());
  return true;
}

TEST(CameraModels, UnprojectThenProjectReturnsEveryPixel) {
  for (const auto& camera : all_models()) {
    SCOPED_TRACE(camera->describe());
    double worst = 0.0;
    int beyond_90_degrees = 0;
    for (int v = 0; v < camera->height(); v += 7) {
      for (int u = 0; u < camera->width(); u += 7) {
        for (const Eigen::Vector2d& pixel :
             {Eigen::Vector2d(u, v), Eigen::Vector2d(camera->width() - 1, v),
              Eigen::Vector2d(u, camera->height() - 1)}) {
          const std::optional<Eigen::Vector3d> ray = camera->unproject(pixel);
          if (!has_forward_ray(*camera, pixel)) {
            EXPECT_FALSE(ray.has_value()) << "pixel " << pixel.transpose();
            ++beyond_90_degrees;
            continue;
          }
          ASSERT_TRUE(ray.has_value()) << "pixel " << pixel.transpose();
          EXPECT_DOUBLE_EQ(ray->z(), 1.0);
          // The ray's scale must not matter.
          const std::optional<Eigen::Vector2d> back = camera->project(2.5 * *ray);
          ASSERT_TRUE(back.has_value()) << "pixel " << pixel.transpose();
          worst = std::max(worst, (*back - pixel).norm());
        }
      }
    }
    EXPECT_LT(worst, 1e-6);
    if (camera->type() == CameraModelType::Pinhole || camera->type() == CameraModelType::RadTan) {
      EXPECT_EQ(beyond_90_degrees, 0);
    }
  }
}

TEST(CameraModels, ProjectThenUnprojectReturnsTheRay) {
  std::mt19937 rng(7);
  for (const auto& camera : all_models()) {
    SCOPED_TRACE(camera->describe());
    std::uniform_real_distribution<double> u(0.0, camera->width() - 1.0);
    std::uniform_real_distribution<double> v(0.0, camera->height() - 1.0);
    std::uniform_real_distribution<double> depth(0.2, 30.0);
    for (int i = 0; i < 500; ++i) {
      // Points that are seen: a ray through a random pixel, at a random depth.
      const Eigen::Vector2d seen(u(rng), v(rng));
      if (!has_forward_ray(*camera, seen)) continue;
      const std::optional<Eigen::Vector3d> ray = camera->unproject(seen);
      ASSERT_TRUE(ray.has_value());
      const Eigen::Vector3d point = depth(rng) * *ray;
      const std::optional<Eigen::Vector2d> pixel = camera->project(point);
      ASSERT_TRUE(pixel.has_value());
      const std::optional<Eigen::Vector3d> back = camera->unproject(*pixel);
      ASSERT_TRUE(back.has_value());
      EXPECT_LT((back->normalized() - point.normalized()).norm(), 1e-10);
    }
  }
}

TEST(CameraModels, PointsBehindOrBesideTheCameraDoNotProject) {
  for (const auto& camera : all_models()) {
    SCOPED_TRACE(camera->describe());
    EXPECT_FALSE(camera->project({0.1, 0.2, -1.0}).has_value());
    EXPECT_FALSE(camera->project({1.0, 0.0, 0.0}).has_value());
    EXPECT_FALSE(camera->project({0.0, 0.0, std::nan("")}).has_value());
    EXPECT_TRUE(camera->project({0.0, 0.0, 1.0}).has_value());
    // The principal point is the optical axis.
    const Eigen::Vector2d centre = *camera->project({0.0, 0.0, 3.0});
    EXPECT_NEAR(centre.x(), camera->cx(), 1e-12);
    EXPECT_NEAR(centre.y(), camera->cy(), 1e-12);
  }
}

TEST(CameraModels, AnalyticJacobianMatchesFiniteDifferences) {
  std::mt19937 rng(11);
  for (const auto& camera : all_models()) {
    SCOPED_TRACE(camera->describe());
    std::uniform_real_distribution<double> u(0.0, camera->width() - 1.0);
    std::uniform_real_distribution<double> v(0.0, camera->height() - 1.0);
    std::uniform_real_distribution<double> depth(0.5, 10.0);
    std::vector<Eigen::Vector3d> points = {{0.0, 0.0, 2.0}, {1e-9, -2e-9, 1.0}};  // on/near the axis
    while (points.size() < 200) {
      const std::optional<Eigen::Vector3d> ray = camera->unproject({u(rng), v(rng)});
      if (ray) points.push_back(depth(rng) * *ray);
    }
    for (const Eigen::Vector3d& p : points) {
      Matrix23d analytic;
      ASSERT_TRUE(camera->project(p, &analytic).has_value());
      Matrix23d numeric;
      for (int k = 0; k < 3; ++k) {
        const double h = 1e-6 * std::max(1.0, p.norm());
        const Eigen::Vector3d dp = h * Eigen::Vector3d::Unit(k);
        numeric.col(k) = (*camera->project(p + dp) - *camera->project(p - dp)) / (2.0 * h);
      }
      // Central differences are accurate to ~1e-7 relative here; a wrong term is off by >1e-2.
      EXPECT_LT((analytic - numeric).norm(), 1e-5 * std::max(1.0, numeric.norm()))
          << "at " << p.transpose() << "\nanalytic\n" << analytic << "\nnumeric\n" << numeric;
    }
  }
}

struct ReferenceProjection {
  Eigen::Vector3d point;
  Eigen::Vector2d pixel;
};

// Produced with cv::projectPoints (OpenCV 4.6, zero rvec/tvec) on the EuRoC cam0 calibration.
// The test executable does not link opencv_calib3d, so the values are recorded here.
const std::vector<ReferenceProjection> kOpenCvEurocRadTan = {
    {{0, 0, 1}, {367.21499999999997, 248.375}},
    {{0.3, -0.2, 1.5}, {457.46276228811519, 188.39338974168481}},
    {{-0.5, 0.35, 1.2}, {189.15707847023882, 372.67086404198824}},
    {{0.62, 0.4, 1}, {613.99423513449665, 407.16137247001802}},
    {{-0.7, -0.45, 1.1}, {115.67213897406327, 87.195362118043164}},
    {{1.2, 0.1, 2.5}, {573.77904050777272, 265.55808587349986}},
    {{-0.05, 0.9, 2}, {356.37340027634212, 442.99343165875234}},
    {{0.4, 0.4, 0.8}, {568.33811339687588, 448.94285600746423}},
};

// Same points, cv::projectPoints with distortion (0.12, -0.05, 0.004, -0.003).
const std::vector<ReferenceProjection> kOpenCvStrongTangential = {
    {{0, 0, 1}, {367.21499999999997, 248.375}},
    {{0.3, -0.2, 1.5}, {459.27906592375302, 187.23352364167903}},
    {{-0.5, 0.35, 1.2}, {169.53670864126298, 386.56485643960985}},
    {{0.62, 0.4, 1}, {665.04667511280741, 441.43319468794886}},
    {{-0.7, -0.45, 1.1}, {59.132598082872789, 52.460037511130025}},
    {{1.2, 0.1, 2.5}, {592.02270968409607, 267.50440140339202}},
    {{-0.05, 0.9, 2}, {355.17032157067871, 459.89287716992192}},
    {{0.4, 0.4, 0.8}, {606.97637850000001, 489.02702000000005}},
};

// cv::fisheye::projectPoints on the TUM-VI style Kannala-Brandt calibration above.
const std::vector<ReferenceProjection> kOpenCvFisheye = {
    {{0, 0, 1}, {254.93170605935475, 256.8974428996504}},
    {{0.3, -0.2, 1.5}, {292.42360858620674, 231.90351785975574}},
    {{-0.5, 0.35, 1.2}, {181.26017074425528, 308.46612153410496}},
    {{0.62, 0.4, 1}, {357.08526536526909, 322.80118086241805}},
    {{-0.7, -0.45, 0.5}, {89.122839842633823, 150.30891450678308}},
    {{1.2, 0.1, 0.4}, {492.97976756432934, 276.73424432926009}},
    {{-0.05, 0.9, 0.3}, {241.68737861976712, 495.28888299203516}},
    {{0.4, 0.4, 0.8}, {338.15666890391299, 340.12015270859285}},
};

void expect_matches(const CameraModel& camera, const std::vector<ReferenceProjection>& references) {
  for (const ReferenceProjection& reference : references) {
    const std::optional<Eigen::Vector2d> pixel = camera.project(reference.point);
    ASSERT_TRUE(pixel.has_value()) << reference.point.transpose();
    EXPECT_NEAR(pixel->x(), reference.pixel.x(), 1e-9) << reference.point.transpose();
    EXPECT_NEAR(pixel->y(), reference.pixel.y(), 1e-9) << reference.point.transpose();
    // And back: the reference pixel unprojects to the reference ray.
    const std::optional<Eigen::Vector3d> ray = camera.unproject(reference.pixel);
    ASSERT_TRUE(ray.has_value());
    EXPECT_LT((ray->normalized() - reference.point.normalized()).norm(), 1e-10);
  }
}

TEST(CameraModels, RadTanAgreesWithOpenCvProjectPoints) {
  expect_matches(euroc_cam0(), kOpenCvEurocRadTan);
  expect_matches(RadTanCamera(752, 480, {458.654, 457.296, 367.215, 248.375},
                              {0.12, -0.05, 0.004, -0.003}),
                 kOpenCvStrongTangential);
}

TEST(CameraModels, EquidistantAgreesWithOpenCvFisheye) {
  expect_matches(tumvi_fisheye(), kOpenCvFisheye);
}

TEST(CameraModels, FovFollowsDevernayFaugeras) {
  const FovCamera camera(640, 480, {300.0, 310.0, 320.0, 240.0}, 0.9);
  // r_d = atan(2 r_u tan(omega/2)) / omega for the point (0.5, -0.25, 1).
  const double r_u = std::hypot(0.5, -0.25);
  const double r_d = std::atan(2.0 * r_u * std::tan(0.45)) / 0.9;
  const Eigen::Vector2d expected(320.0 + 300.0 * 0.5 * r_d / r_u, 240.0 - 310.0 * 0.25 * r_d / r_u);
  const Eigen::Vector2d pixel = *camera.project({1.0, -0.5, 2.0});
  EXPECT_NEAR((pixel - expected).norm(), 0.0, 1e-10);
  // Rays at 90 degrees and more have no pixel, and pixels beyond r_d = pi / (2 omega) no ray.
  const double beyond = std::numbers::pi / (2.0 * 0.9) + 0.01;
  EXPECT_FALSE(camera.unproject({320.0 + 300.0 * beyond, 240.0}).has_value());
  EXPECT_TRUE(camera.unproject({320.0 + 300.0 * (beyond - 0.02), 240.0}).has_value());
  EXPECT_THROW(FovCamera(640, 480, {300.0, 310.0, 320.0, 240.0}, 0.0), std::invalid_argument);
  EXPECT_THROW(FovCamera(640, 480, {300.0, 310.0, 320.0, 240.0}, 3.2), std::invalid_argument);
}

TEST(CameraModels, RadTanBeyondItsFoldDoesNotProject) {
  // k1 = -0.5: r (1 - 0.5 r^2) peaks at r^2 = 2/3 with r_d = 0.544; beyond, a second, wrong
  // solution exists. Neither direction may return it.
  const RadTanCamera camera(640, 480, {400.0, 400.0, 320.0, 240.0}, {-0.5, 0.0, 0.0, 0.0});
  EXPECT_NEAR(camera.max_radius_squared(), 2.0 / 3.0, 1e-15);
  EXPECT_TRUE(camera.project({0.8, 0.0, 1.0}).has_value());
  EXPECT_FALSE(camera.project({0.9, 0.0, 1.0}).has_value());
  EXPECT_TRUE(camera.unproject({320.0 + 400.0 * 0.54, 240.0}).has_value());
  EXPECT_FALSE(camera.unproject({320.0 + 400.0 * 0.55, 240.0}).has_value());
  // Without a fold (EuRoC: the radial polynomial always grows) there is no limit.
  EXPECT_TRUE(std::isinf(euroc_cam0().max_radius_squared()));
}

TEST(CameraModels, EquidistantBeyondItsFoldDoesNotProject) {
  // k1 = -0.3: theta (1 - 0.3 theta^2) peaks at theta = sqrt(1 / 0.9).
  const EquidistantCamera camera(640, 480, {300.0, 300.0, 320.0, 240.0}, {-0.3, 0.0, 0.0, 0.0});
  EXPECT_NEAR(camera.max_theta(), std::sqrt(1.0 / 0.9), 1e-12);
  EXPECT_TRUE(camera.project({std::tan(1.0), 0.0, 1.0}).has_value());
  EXPECT_FALSE(camera.project({std::tan(1.1), 0.0, 1.0}).has_value());
  EXPECT_DOUBLE_EQ(tumvi_fisheye().max_theta(), std::numbers::pi / 2.0);
}

TEST(CameraModels, ConstructorsRejectNonsense) {
  EXPECT_THROW(PinholeCamera(0, 480, {500.0, 500.0, 320.0, 240.0}), std::invalid_argument);
  EXPECT_THROW(PinholeCamera(640, 480, {-500.0, 500.0, 320.0, 240.0}), std::invalid_argument);
  EXPECT_THROW(PinholeCamera(640, 480, {500.0, std::nan(""), 320.0, 240.0}), std::invalid_argument);
  EXPECT_THROW(RadTanCamera(640, 480, {500.0, 500.0, 320.0, 240.0},
                            {0.1, std::numeric_limits<double>::infinity(), 0.0, 0.0}),
               std::invalid_argument);
}

TEST(CameraModels, CloneKeepsTypeAndParameters) {
  for (const auto& camera : all_models()) {
    const std::unique_ptr<CameraModel> copy = camera->clone();
    EXPECT_EQ(copy->type(), camera->type());
    EXPECT_EQ(copy->describe(), camera->describe());
    const Eigen::Vector3d p(0.1, -0.2, 1.3);
    EXPECT_EQ(*copy->project(p), *camera->project(p));
  }
  EXPECT_EQ(euroc_cam0().name(), "RadTan");
  EXPECT_EQ(tum_monovo_fov().distortion().size(), 1);
  EXPECT_EQ(tumvi_fisheye().distortion().size(), 4);
}

}  // namespace
}  // namespace nirslam
