#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "nirslam/image/image_codec.hpp"
#include "nirslam/quality/image_quality.hpp"

namespace nirslam {
namespace {

cv::Mat filled(int rows, int cols, int type, double value) {
  return cv::Mat(rows, cols, type, cv::Scalar(value));
}

TEST(Entropy, ConstantImageHasZeroBits) {
  EXPECT_DOUBLE_EQ(measure_quality(filled(48, 64, CV_8UC1, 77), 8).entropy_bits, 0.0);
}

TEST(Entropy, TwoEqualHalvesHaveOneBit) {
  cv::Mat image = filled(10, 10, CV_8UC1, 0);
  image.rowRange(0, 5).setTo(200);
  EXPECT_NEAR(measure_quality(image, 8).entropy_bits, 1.0, 1e-12);
}

TEST(Entropy, EveryValueOnceHasEightBits) {
  cv::Mat image(16, 16, CV_8UC1);
  for (int i = 0; i < 256; ++i) image.at<std::uint8_t>(i / 16, i % 16) = static_cast<std::uint8_t>(i);
  EXPECT_NEAR(measure_quality(image, 8).entropy_bits, 8.0, 1e-12);
}

TEST(Entropy, UnequalProbabilitiesMatchHandComputation) {
  // p = 1/2, 1/4, 1/8, 1/8  ->  H = 0.5*1 + 0.25*2 + 2 * 0.125*3 = 1.75 bits
  cv::Mat image(1, 8, CV_8UC1);
  const std::uint8_t values[8] = {10, 10, 10, 10, 20, 20, 30, 40};
  for (int i = 0; i < 8; ++i) image.at<std::uint8_t>(0, i) = values[i];
  EXPECT_NEAR(measure_quality(image, 8).entropy_bits, 1.75, 1e-12);
}

TEST(Entropy, SixteenBitImagesAreBinnedByTheirSignificantBits) {
  // A 10-bit ramp over every code fills each of the 256 bins with 4 codes: 8 bits.
  cv::Mat ramp(1, 1024, CV_16UC1);
  for (int i = 0; i < 1024; ++i) ramp.at<std::uint16_t>(0, i) = static_cast<std::uint16_t>(i);
  EXPECT_NEAR(measure_quality(ramp, 10).entropy_bits, 8.0, 1e-12);
  // The same codes read as 16-bit data all fall in the lowest 4 bins (1024 / 256 codes each).
  EXPECT_NEAR(measure_quality(ramp, 16).entropy_bits, 2.0, 1e-12);
  // Codes 0..3 of a 10-bit image share bin 0: no information at 8-bit resolution.
  cv::Mat dark(1, 4, CV_16UC1);
  for (int i = 0; i < 4; ++i) dark.at<std::uint16_t>(0, i) = static_cast<std::uint16_t>(i);
  EXPECT_DOUBLE_EQ(measure_quality(dark, 10).entropy_bits, 0.0);
}

TEST(Entropy, EightBitAndScaledSixteenBitAgree) {
  cv::Mat image8(60, 80, CV_8UC1);
  cv::randu(image8, 0, 256);
  cv::Mat image16;
  image8.convertTo(image16, CV_16UC1, 256.0);
  EXPECT_NEAR(measure_quality(image8, 8).entropy_bits, measure_quality(image16, 16).entropy_bits, 1e-12);
}

TEST(Clipping, CountsTopAndBottomCodesOfTheBitDepth) {
  cv::Mat image = filled(10, 10, CV_16UC1, 2000);
  image.row(0).setTo(4095);   // saturated for 12 bits
  image.row(1).setTo(65535);  // above the 12-bit range: corrupt, counted as saturated
  image.rowRange(2, 5).setTo(0);
  image.at<std::uint16_t>(9, 9) = 4094;  // one below the top code is not saturated
  const ImageQuality quality = measure_quality(image, 12);
  EXPECT_DOUBLE_EQ(quality.saturated_fraction, 0.20);
  EXPECT_DOUBLE_EQ(quality.black_fraction, 0.30);
}

TEST(Clipping, EightBitSaturationIs255) {
  cv::Mat image = filled(4, 5, CV_8UC1, 254);
  image.row(0).setTo(255);
  EXPECT_DOUBLE_EQ(measure_quality(image, 8).saturated_fraction, 0.25);
  EXPECT_DOUBLE_EQ(measure_quality(image, 8).black_fraction, 0.0);
}

TEST(ImageQuality, RejectsColourEmptyAndMislabelledImages) {
  EXPECT_THROW(measure_quality(cv::Mat(4, 4, CV_8UC3), 8), std::invalid_argument);
  EXPECT_THROW(measure_quality(cv::Mat(), 8), std::invalid_argument);
  EXPECT_THROW(measure_quality(cv::Mat(4, 4, CV_8UC1), 12), std::invalid_argument);
  EXPECT_THROW(measure_quality(cv::Mat(4, 4, CV_16UC1), 8), std::invalid_argument);
  EXPECT_THROW(measure_quality(cv::Mat(4, 4, CV_32FC1), 8), std::invalid_argument);
}

// An independent computation on a real EuRoC frame: OpenCV's calcHist and the formula written out.
TEST(Entropy, RealFrameMatchesIndependentHistogram) {
  const std::filesystem::path path = std::filesystem::path(NIRSLAM_SHARED_DATA_DIR) /
                                     "euroc_v1_01_micro/mav0/cam0/data/1403715273262142976.png";
  const cv::Mat image = nirslam::read_image(path);
  ASSERT_FALSE(image.empty()) << path;
  cv::Mat histogram;
  const int channels[] = {0};
  const int bins[] = {256};
  const float range[] = {0.0f, 256.0f};
  const float* ranges[] = {range};
  cv::calcHist(&image, 1, channels, cv::Mat(), histogram, 1, bins, ranges);
  double expected = 0.0;
  for (int i = 0; i < 256; ++i) {
    const double p = histogram.at<float>(i) / static_cast<double>(image.total());
    if (p > 0) expected -= p * std::log(p) / std::log(2.0);
  }
  EXPECT_NEAR(measure_quality(image, 8).entropy_bits, expected, 1e-9);
  // Also against the stdlib-only Python reference (tests/tools/entropy_reference.py).
  EXPECT_NEAR(measure_quality(image, 8).entropy_bits, 6.973564225, 1e-6);
}

}  // namespace
}  // namespace nirslam
