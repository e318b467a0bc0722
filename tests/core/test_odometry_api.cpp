// The public contract of DirectOdometry that needs no sequence: input checks and names.

#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/odometry/direct_odometry.hpp"

namespace nirslam {
namespace {

PinholeCamera small_camera() { return PinholeCamera(80, 60, Eigen::Vector4d(60.0, 60.0, 39.5, 29.5)); }

TEST(OdometryApi, WrongImageTypeOrSizeNamesTheField) {
  DirectOdometry odometry(small_camera());
  OdometryFrame frame;
  frame.image = cv::Mat(60, 80, CV_8UC1, cv::Scalar(10));
  try {
    odometry.process(frame);
    FAIL() << "an 8-bit image was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("OdometryFrame.image"), std::string::npos) << e.what();
  }
  frame.image = cv::Mat(61, 80, CV_32FC1, cv::Scalar(10));
  EXPECT_THROW(odometry.process(frame), std::invalid_argument);
  frame.image = cv::Mat(60, 80, CV_32FC1, cv::Scalar(10));
  frame.exposure = -1.0;
  EXPECT_THROW(odometry.process(frame), std::invalid_argument);
}

TEST(OdometryApi, TheBeamExponentOfAFrameIsCheckedAndTakenFromThenOn) {
  OdometryOptions options;
  options.illuminator_correction = true;
  options.beam_exponent = 2.0;
  DirectOdometry odometry(small_camera(), options);
  OdometryFrame frame;
  frame.image = cv::Mat(60, 80, CV_32FC1, cv::Scalar(100));
  frame.beam_exponent = std::numeric_limits<double>::quiet_NaN();
  try {
    odometry.process(frame);
    FAIL() << "a beam exponent NaN was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("OdometryFrame.beam_exponent"), std::string::npos) << e.what();
  }
  EXPECT_DOUBLE_EQ(odometry.options().beam_exponent, 2.0) << "a refused frame changes nothing";
  frame.beam_exponent = 4.82;
  odometry.process(frame);
  EXPECT_DOUBLE_EQ(odometry.options().beam_exponent, 4.82);
  frame.beam_exponent.reset();  // a frame without one keeps the last
  frame.frame_index = 1;
  odometry.process(frame);
  EXPECT_DOUBLE_EQ(odometry.options().beam_exponent, 4.82);
  // Negative: the frames were corrected for a stronger beam than the lamp's.
  frame.beam_exponent = -1.5;
  frame.frame_index = 2;
  odometry.process(frame);
  EXPECT_DOUBLE_EQ(odometry.options().beam_exponent, -1.5);
}

TEST(OdometryApi, FlatImagesNeverCrashAndGivePosesOnlyOnceInitialised) {
  DirectOdometry odometry(small_camera());
  OdometryFrame frame;
  frame.image = cv::Mat(60, 80, CV_32FC1, cv::Scalar(100));
  for (int i = 0; i < 5; ++i) {
    frame.frame_index = i;
    const OdometryResult r = odometry.process(frame);
    EXPECT_EQ(r.status, TrackingStatus::Initialising);
    EXPECT_FALSE(r.T_world_cam.has_value());
  }
  EXPECT_TRUE(odometry.trajectory().empty());
  EXPECT_TRUE(odometry.points().empty());
  odometry.reset();
  EXPECT_TRUE(odometry.keyframes().empty());
}

TEST(OdometryApi, ALampNotModelledLeavesTheAffineBrightnessFree) {
  // Exposures explain the brightness only when no lamp the odometry does not model is on: the
  // co-located lamp brightens each surface as the rig approaches it (README, "Illuminator
  // correction": the calibrated mode under the lamp, better on 8 of the 12 bench sequences).
  struct Case {
    std::optional<double> exposure, power_w;
    bool lamp_modelled, explains;
  };
  for (const Case& c : {Case{10.0, std::nullopt, false, true}, Case{10.0, 0.0, false, true}, Case{10.0, 50.0, false, false},
                        Case{10.0, 50.0, true, true}, Case{std::nullopt, std::nullopt, false, false}}) {
    OdometryOptions options;
    options.illuminator_correction = c.lamp_modelled;
    DirectOdometry odometry(small_camera(), options);
    OdometryFrame frame;
    frame.image = cv::Mat(60, 80, CV_32FC1, cv::Scalar(100));
    frame.exposure = c.exposure;
    frame.illuminator_power_w = c.power_w;
    odometry.process(frame);
    EXPECT_EQ(odometry.exposure_explains_brightness(), c.explains)
        << "exposure " << c.exposure.has_value() << ", power " << c.power_w.value_or(-1.0) << ", modelled " << c.lamp_modelled;
  }
}

TEST(OdometryApi, AnUntrustedLampFactorCountsAsALampNotModelled) {
  // The pipeline withholds the factor until the camera response is fitted
  // (PipelineOptions::lamp_factor_waits_for_response); the frame follows its own flag.
  OdometryOptions options;
  options.illuminator_correction = true;
  DirectOdometry odometry(small_camera(), options);
  OdometryFrame frame;
  frame.image = cv::Mat(60, 80, CV_32FC1, cv::Scalar(100));
  frame.exposure = 10.0;
  frame.illuminator_power_w = 50.0;
  for (const bool trusted : {false, true, false, true}) {
    frame.lamp_factor_trusted = trusted;
    odometry.process(frame);
    ++frame.frame_index;
    EXPECT_EQ(odometry.exposure_explains_brightness(), trusted) << "frame " << frame.frame_index - 1;
  }
  EXPECT_TRUE(odometry.options().illuminator_correction) << "the option stays; the frames choose";
}

TEST(OdometryApi, StatusNames) {
  EXPECT_STREQ(to_string(TrackingStatus::Initialising), "initialising");
  EXPECT_STREQ(to_string(TrackingStatus::Tracking), "tracking");
  EXPECT_STREQ(to_string(TrackingStatus::Lost), "lost");
  EXPECT_STREQ(to_string(TrackingStatus::NewSegment), "new segment");
}

}  // namespace
}  // namespace nirslam
