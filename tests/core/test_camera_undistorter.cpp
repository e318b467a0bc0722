// Undistortion: synthetic images rendered through a distorted model come out as the ideal pinhole
// image, straight lines come out straight, and the output-camera choices (crop, full, same K,
// explicit) do what their names say.

#include <cmath>
#include <functional>
#include <numbers>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "camera_fixtures.hpp"
#include "nirslam/camera/camera_model.hpp"
#include "nirslam/camera/undistorter.hpp"

namespace nirslam {
namespace {

using namespace test_cameras;

// A scene drawn on the z = 1 plane, as a function of undistorted normalised coordinates.
using PlaneTexture = std::function<double(double x, double y)>;

// What `camera` sees of the texture: each pixel samples the texture where its ray meets z = 1.
cv::Mat render(const CameraModel& camera, const PlaneTexture& texture, int type, double scale) {
  cv::Mat image(camera.height(), camera.width(), type, cv::Scalar(0));
  for (int v = 0; v < camera.height(); ++v) {
    for (int u = 0; u < camera.width(); ++u) {
      const std::optional<Eigen::Vector3d> ray = camera.unproject(Eigen::Vector2d(u, v));
      if (!ray) continue;
      const double value = std::round(scale * texture(ray->x(), ray->y()));
      if (type == CV_8UC1)
        image.at<std::uint8_t>(v, u) = cv::saturate_cast<std::uint8_t>(value);
      else
        image.at<std::uint16_t>(v, u) = cv::saturate_cast<std::uint16_t>(value);
    }
  }
  return image;
}

double smooth_texture(double x, double y) {
  // Periods of ~50 px in the EuRoC image: bilinear resampling is accurate to a small fraction of
  // a grey level on it, so any error of geometry shows.
  return 128.0 + 90.0 * std::sin(2.0 * std::numbers::pi * x / 0.11) *
                     std::cos(2.0 * std::numbers::pi * y / 0.13 + 0.3);
}

struct Difference {
  double mean = 0.0;
  double max = 0.0;
};

Difference compare_valid(const cv::Mat& actual, const cv::Mat& expected, const cv::Mat& mask) {
  cv::Mat a, e;
  actual.convertTo(a, CV_64F);
  expected.convertTo(e, CV_64F);
  const cv::Mat difference = cv::abs(a - e);
  Difference result;
  result.mean = cv::mean(difference, mask)[0];
  cv::minMaxLoc(difference, nullptr, &result.max, nullptr, nullptr, mask);
  return result;
}

TEST(CameraUndistorter, UndistortedImageMatchesTheIdealPinholeImage) {
  const RadTanCamera input = euroc_cam0();
  const PinholeCamera output = make_crop_pinhole(input, 640, 400);
  const Undistorter undistorter(input, output);

  const cv::Mat distorted = render(input, smooth_texture, CV_8UC1, 1.0);
  const cv::Mat expected = render(output, smooth_texture, CV_8UC1, 1.0);
  const cv::Mat undistorted = undistorter.undistort(distorted);
  ASSERT_EQ(undistorted.size(), cv::Size(640, 400));
  ASSERT_EQ(undistorted.type(), CV_8UC1);
  EXPECT_EQ(undistorter.valid_fraction(), 1.0);  // crop: every output pixel has a source

  const Difference difference = compare_valid(undistorted, expected, undistorter.valid_mask());
  EXPECT_LT(difference.mean, 0.6);
  EXPECT_LT(difference.max, 3.0);
  // The distortion is strong enough that skipping the undistortion would be caught: the raw image
  // differs clearly from the pinhole image with the same intrinsics.
  const cv::Mat same_k = render(make_same_k_pinhole(input), smooth_texture, CV_8UC1, 1.0);
  const cv::Mat everywhere(distorted.size(), CV_8UC1, cv::Scalar(255));
  EXPECT_GT(compare_valid(distorted, same_k, everywhere).mean, 20.0);
}

TEST(CameraUndistorter, SixteenBitImagesKeepTheirRange) {
  const RadTanCamera input = euroc_cam0();
  const Undistorter undistorter(input, RectificationSpec{RectificationMode::Crop, 640, 400});
  const cv::Mat distorted = render(input, smooth_texture, CV_16UC1, 256.0);
  const cv::Mat expected = render(undistorter.output_camera(), smooth_texture, CV_16UC1, 256.0);
  const cv::Mat undistorted = undistorter.undistort(distorted);
  ASSERT_EQ(undistorted.type(), CV_16UC1);
  const Difference difference = compare_valid(undistorted, expected, undistorter.valid_mask());
  EXPECT_LT(difference.mean, 0.6 * 256.0);
  EXPECT_LT(difference.max, 3.0 * 256.0);
  double max_value = 0.0;
  cv::minMaxLoc(undistorted, nullptr, &max_value);
  EXPECT_GT(max_value, 200.0 * 256.0);
}

TEST(CameraUndistorter, StraightLinesComeOutStraight) {
  const FovCamera input = tum_monovo_fov();
  const PinholeCamera output = make_crop_pinhole(input, 640, 480);
  const Undistorter undistorter(input, output);
  // Dark vertical lines x = c on the z = 1 plane, 1.2 output pixels wide.
  const std::vector<double> lines = {-0.6, -0.3, 0.0, 0.25, 0.55};
  const PlaneTexture texture = [&](double x, double) {
    double nearest = 1e9;
    for (const double c : lines) nearest = std::min(nearest, std::abs(x - c) * output.fx());
    return 230.0 - 180.0 * std::exp(-nearest * nearest / (1.2 * 1.2));
  };
  const cv::Mat distorted = render(input, texture, CV_8UC1, 1.0);

  // In the fish-eye input the outer lines bend by many pixels between the top and the middle.
  const double middle_u = input.project({lines.front(), 0.0, 1.0})->x();
  const double top_u = input.project({lines.front(), output.unproject({0.0, 0.0})->y(), 1.0})->x();
  EXPECT_GT(std::abs(top_u - middle_u), 10.0);

  const cv::Mat undistorted = undistorter.undistort(distorted);
  double worst = 0.0;
  for (const double c : lines) {
    const double expected_u = output.fx() * c + output.cx();
    ASSERT_GT(expected_u, 6.0);
    ASSERT_LT(expected_u, output.width() - 7.0);
    for (int v = 0; v < output.height(); ++v) {
      // Centroid of darkness across the line in this row.
      double weight = 0.0, moment = 0.0;
      for (int u = static_cast<int>(expected_u) - 5; u <= static_cast<int>(expected_u) + 6; ++u) {
        const double darkness = 230.0 - undistorted.at<std::uint8_t>(v, u);
        weight += darkness;
        moment += darkness * u;
      }
      ASSERT_GT(weight, 100.0) << "no line near u = " << expected_u << " in row " << v;
      worst = std::max(worst, std::abs(moment / weight - expected_u));
    }
  }
  EXPECT_LT(worst, 0.05);  // measured 0.016: the centroid of a 1.2 px wide line
}

TEST(CameraUndistorter, CropIsValidEverywhereAndTight) {
  for (const std::shared_ptr<const CameraModel>& input :
       {std::shared_ptr<const CameraModel>(std::make_shared<RadTanCamera>(euroc_cam0())),
        std::shared_ptr<const CameraModel>(std::make_shared<FovCamera>(tum_monovo_fov()))}) {
    SCOPED_TRACE(input->describe());
    const PinholeCamera crop = make_crop_pinhole(*input, 640, 480);
    EXPECT_EQ(Undistorter(*input, crop).valid_fraction(), 1.0);
    // A view 3 % wider about the same centre already reaches outside the input image.
    const double s = 0.97;
    const PinholeCamera wider(640, 480,
                              {crop.fx() * s, crop.fy() * s, (crop.cx() - 319.5) * s + 319.5,
                               (crop.cy() - 239.5) * s + 239.5});
    EXPECT_LT(Undistorter(*input, wider).valid_fraction(), 1.0);
  }
}

TEST(CameraUndistorter, FullViewContainsTheWholeInputImage) {
  const RadTanCamera input = euroc_cam0();
  const PinholeCamera full = make_full_pinhole(input, 752, 480);
  double min_u = 1e9, max_u = -1e9, min_v = 1e9, max_v = -1e9;
  const auto visit = [&](double u, double v) {
    const Eigen::Vector2d pixel = *full.project(*input.unproject({u, v}));
    min_u = std::min(min_u, pixel.x());
    max_u = std::max(max_u, pixel.x());
    min_v = std::min(min_v, pixel.y());
    max_v = std::max(max_v, pixel.y());
  };
  for (int u = 0; u < input.width(); ++u) {
    visit(u, 0);
    visit(u, input.height() - 1);
  }
  for (int v = 0; v < input.height(); ++v) {
    visit(0, v);
    visit(input.width() - 1, v);
  }
  // The input border just touches all four output borders.
  EXPECT_NEAR(min_u, 0.0, 1e-6);
  EXPECT_NEAR(max_u, 751.0, 1e-6);
  EXPECT_NEAR(min_v, 0.0, 1e-6);
  EXPECT_NEAR(max_v, 479.0, 1e-6);

  // Barrel distortion: the output's corners see nothing, and those pixels are 0 and masked.
  const Undistorter undistorter(input, full);
  EXPECT_LT(undistorter.valid_fraction(), 0.98);
  EXPECT_GT(undistorter.valid_fraction(), 0.6);
  EXPECT_EQ(undistorter.valid_mask().at<std::uint8_t>(0, 0), 0);
  EXPECT_EQ(undistorter.valid_mask().at<std::uint8_t>(240, 376), 255);
  const cv::Mat bright(480, 752, CV_8UC1, cv::Scalar(200));
  const cv::Mat out = undistorter.undistort(bright);
  cv::Mat invalid;
  cv::bitwise_not(undistorter.valid_mask(), invalid);
  EXPECT_EQ(cv::countNonZero(out & invalid), 0);
  // Every valid pixel is a full-weight interpolation of 200s: no darkened rim at the border.
  double min_valid = 0.0;
  cv::minMaxLoc(out, &min_valid, nullptr, nullptr, nullptr, undistorter.valid_mask());
  EXPECT_EQ(min_valid, 200.0);
  EXPECT_EQ(undistorter.map_x().at<float>(0, 0), -1.0f);

  // FOV lenses whose corners see past 90 degrees have no pinhole 'full' view.
  EXPECT_THROW(make_full_pinhole(tum_monovo_fov(), 640, 480), std::invalid_argument);
}

TEST(CameraUndistorter, SameKAndExplicitOutputs) {
  const RadTanCamera input = euroc_cam0();
  const PinholeCamera same = make_output_pinhole(input, {RectificationMode::SameK, 0, 0});
  EXPECT_EQ(same.intrinsics(), input.intrinsics());
  EXPECT_EQ(same.width(), 752);
  EXPECT_THROW(make_output_pinhole(input, {RectificationMode::SameK, 640, 480}),
               std::invalid_argument);
  const Eigen::Vector4d k(300.0, 301.0, 319.5, 239.5);
  const PinholeCamera explicit_k =
      make_output_pinhole(input, {RectificationMode::Explicit, 640, 480, k});
  EXPECT_EQ(explicit_k.intrinsics(), k);
  EXPECT_EQ(explicit_k.height(), 480);
  const PinholeCamera crop_default_size = make_output_pinhole(input, RectificationSpec{});
  EXPECT_EQ(crop_default_size.width(), 752);
  EXPECT_EQ(crop_default_size.height(), 480);
  EXPECT_THROW(make_crop_pinhole(input, 1, 480), std::invalid_argument);
}

TEST(CameraUndistorter, PinholeToSamePinholeIsAnExactCopy) {
  const PinholeCamera camera(64, 48, {50.0, 50.0, 31.5, 23.5});
  const Undistorter undistorter(camera, camera);
  EXPECT_TRUE(undistorter.is_identity());
  cv::Mat image(48, 64, CV_16UC1);
  cv::randu(image, 0, 65535);
  const cv::Mat out = undistorter.undistort(image);
  EXPECT_EQ(cv::norm(out, image, cv::NORM_INF), 0.0);
  EXPECT_NE(out.data, image.data);  // a copy: the caller may modify either
  EXPECT_FALSE(Undistorter(camera, PinholeCamera(64, 48, {50.0, 50.0, 31.0, 23.5})).is_identity());
}

TEST(CameraUndistorter, FrameKeepsItsMetadata) {
  const RadTanCamera input = euroc_cam0();
  const Undistorter undistorter(input, make_crop_pinhole(input, 640, 400));
  Frame frame;
  frame.image = cv::Mat(480, 752, CV_16UC1, cv::Scalar(1000));
  frame.bit_depth = 12;
  frame.timestamp_s = 1403715273.262143;
  frame.index = 17;
  frame.exposure_ms = 4.5;
  frame.gain = 2.0;
  frame.illuminator_power_w = 30.0;
  frame.name = "1403715273262142976.png";
  const Frame out = undistorter.undistort(frame);
  EXPECT_EQ(out.image.size(), cv::Size(640, 400));
  EXPECT_EQ(out.image.type(), CV_16UC1);
  EXPECT_EQ(out.bit_depth, 12);
  EXPECT_EQ(out.timestamp_s, frame.timestamp_s);
  EXPECT_EQ(out.index, 17);
  EXPECT_EQ(out.exposure_ms, 4.5);
  EXPECT_EQ(out.gain, 2.0);
  EXPECT_EQ(out.illuminator_power_w, 30.0);
  EXPECT_EQ(out.name, frame.name);
  EXPECT_EQ(out.image.at<std::uint16_t>(200, 320), 1000);
}

TEST(CameraUndistorter, RejectsImagesOfAnotherSizeOrType) {
  const RadTanCamera input = euroc_cam0();
  const Undistorter undistorter(input, make_crop_pinhole(input, 640, 400));
  EXPECT_THROW(undistorter.undistort(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0))),
               std::invalid_argument);
  EXPECT_THROW(undistorter.undistort(cv::Mat(480, 752, CV_8UC3, cv::Scalar(0))),
               std::invalid_argument);
  EXPECT_THROW(undistorter.undistort(cv::Mat(480, 752, CV_32FC1, cv::Scalar(0))),
               std::invalid_argument);
}

TEST(CameraUndistorter, RelativeIntrinsicsFollowDso) {
  // DSO: fx * w, fy * h, cx * w - 0.5, cy * h - 0.5.
  const Eigen::Vector4d absolute =
      absolute_from_relative_intrinsics({0.5, 0.75, 0.5, 0.5}, 640, 480);
  EXPECT_EQ(absolute, Eigen::Vector4d(320.0, 360.0, 319.5, 239.5));
}

}  // namespace
}  // namespace nirslam
