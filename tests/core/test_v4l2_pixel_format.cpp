// Pixel conversion from hand-made buffers, one per V4L2 format nirslam takes, with the bit
// layouts the V4L2 documentation gives: Y10/Y12/Y16 are little-endian 16-bit words with the value
// in the low bits, YUYV keeps luma at even bytes, rows may be padded (bytesperline).

#include <cstdint>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <opencv2/core.hpp>

#include "nirslam/capture/pixel_format.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {
namespace {

// Little-endian 16-bit words of `values`, rows of `width` padded to `stride` bytes with 0xEE.
std::vector<std::uint8_t> words(const std::vector<std::uint16_t>& values, int width, int stride) {
  const int height = static_cast<int>(values.size()) / width;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(stride * height), 0xEE);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const std::uint16_t v = values[y * width + x];
      bytes[y * stride + 2 * x] = static_cast<std::uint8_t>(v & 0xFF);
      bytes[y * stride + 2 * x + 1] = static_cast<std::uint8_t>(v >> 8);
    }
  return bytes;
}

TEST(V4l2PixelFormat, FourccsNamesAndDepths) {
  EXPECT_EQ(fourcc_of(PixelFormat::Grey), V4L2_PIX_FMT_GREY);
  EXPECT_EQ(fourcc_of(PixelFormat::Y10), v4l2_fourcc('Y', '1', '0', ' '));
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_Y10), "Y10");
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_MJPEG), "MJPG");
  EXPECT_EQ(pixel_format_from_fourcc(V4L2_PIX_FMT_JPEG), PixelFormat::Mjpg);
  EXPECT_FALSE(pixel_format_from_fourcc(V4L2_PIX_FMT_RGB24).has_value());
  EXPECT_EQ(pixel_format_from_name("y12"), PixelFormat::Y12);
  EXPECT_EQ(pixel_format_from_name("MJPEG"), PixelFormat::Mjpg);
  EXPECT_FALSE(pixel_format_from_name("RGB3").has_value());
  EXPECT_EQ(bit_depth_of(PixelFormat::Grey), 8);
  EXPECT_EQ(bit_depth_of(PixelFormat::Y10), 10);
  EXPECT_EQ(bit_depth_of(PixelFormat::Y12), 12);
  EXPECT_EQ(bit_depth_of(PixelFormat::Y16), 16);
  EXPECT_EQ(bit_depth_of(PixelFormat::Yuyv), 8);
}

TEST(V4l2PixelFormat, GreyWithPaddedRows) {
  // 3x2 pixels, rows padded to 5 bytes: the padding must not leak into the image.
  const std::vector<std::uint8_t> bytes{10, 20, 30, 0xEE, 0xEE, 40, 50, 60};
  const cv::Mat image = convert_buffer({PixelFormat::Grey, 3, 2, 5}, bytes);
  ASSERT_EQ(image.type(), CV_8UC1);
  ASSERT_EQ(image.size(), cv::Size(3, 2));
  EXPECT_EQ(image.at<std::uint8_t>(0, 0), 10);
  EXPECT_EQ(image.at<std::uint8_t>(0, 2), 30);
  EXPECT_EQ(image.at<std::uint8_t>(1, 0), 40);
  EXPECT_EQ(image.at<std::uint8_t>(1, 2), 60);
}

TEST(V4l2PixelFormat, Y10KeepsTheLowTenBitsOfLittleEndianWords) {
  // 1023 is full scale; 0x0201 = 513 tells byte order apart; 0xFC00 | 5 carries garbage above bit 9.
  const std::vector<std::uint16_t> values{0, 1023, 0x0201, 0xFC00 | 5};
  const cv::Mat image = convert_buffer({PixelFormat::Y10, 2, 2, 6}, words(values, 2, 6));
  ASSERT_EQ(image.type(), CV_16UC1);
  EXPECT_EQ(image.at<std::uint16_t>(0, 0), 0);
  EXPECT_EQ(image.at<std::uint16_t>(0, 1), 1023);
  EXPECT_EQ(image.at<std::uint16_t>(1, 0), 513);
  EXPECT_EQ(image.at<std::uint16_t>(1, 1), 5);
}

TEST(V4l2PixelFormat, Y12AndY16) {
  const std::vector<std::uint16_t> y12{4095, 0x0ABC, 0xF001, 7};
  const cv::Mat a = convert_buffer({PixelFormat::Y12, 4, 1, 0}, words(y12, 4, 8));
  EXPECT_EQ(a.at<std::uint16_t>(0, 0), 4095);
  EXPECT_EQ(a.at<std::uint16_t>(0, 1), 0x0ABC);
  EXPECT_EQ(a.at<std::uint16_t>(0, 2), 1);  // bits above 11 are not part of a Y12 value
  EXPECT_EQ(a.at<std::uint16_t>(0, 3), 7);
  const std::vector<std::uint16_t> y16{65535, 0x1234, 0x8000, 1};
  const cv::Mat b = convert_buffer({PixelFormat::Y16, 2, 2, 0}, words(y16, 2, 4));
  EXPECT_EQ(b.at<std::uint16_t>(0, 0), 65535);
  EXPECT_EQ(b.at<std::uint16_t>(0, 1), 0x1234);
  EXPECT_EQ(b.at<std::uint16_t>(1, 0), 0x8000);
  EXPECT_EQ(b.at<std::uint16_t>(1, 1), 1);
}

TEST(V4l2PixelFormat, YuyvKeepsLuma) {
  // Two rows of Y0 U Y1 V: luma 1, 2, 3, 4 / 5, 6, 7, 8 among chroma values that must be ignored.
  const std::vector<std::uint8_t> bytes{1, 200, 2, 100, 3, 201, 4, 101, 5, 202, 6, 102, 7, 203, 8, 103};
  const cv::Mat image = convert_buffer({PixelFormat::Yuyv, 4, 2, 8}, bytes);
  ASSERT_EQ(image.type(), CV_8UC1);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(image.at<std::uint8_t>(i / 4, i % 4), i + 1) << i;
}

TEST(V4l2PixelFormat, MjpgDecodesToGrey) {
  cv::Mat grey(24, 32, CV_8UC1);
  for (int y = 0; y < grey.rows; ++y)
    for (int x = 0; x < grey.cols; ++x) grey.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(40 + 4 * x + 2 * y);
  const std::vector<std::uint8_t> jpeg = encode_jpeg(grey, 98);
  const cv::Mat image = convert_buffer({PixelFormat::Mjpg, 32, 24, 0}, jpeg);
  ASSERT_EQ(image.type(), CV_8UC1);
  ASSERT_EQ(image.size(), grey.size());
  EXPECT_LE(cv::norm(image, grey, cv::NORM_INF), 3.0);  // JPEG at quality 98 on a smooth ramp
  // A frame of another size than negotiated, or garbage, is refused with the sizes named.
  try {
    convert_buffer({PixelFormat::Mjpg, 64, 48, 0}, jpeg);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("32x24"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("MJPG 64x48"), std::string::npos) << e.what();
  }
  const std::vector<std::uint8_t> garbage(100, 0x42);
  EXPECT_THROW(convert_buffer({PixelFormat::Mjpg, 32, 24, 0}, garbage), std::invalid_argument);
}

TEST(V4l2PixelFormat, ShortBufferIsAnErrorNamingTheLayout) {
  const std::vector<std::uint8_t> bytes(10);
  try {
    convert_buffer({PixelFormat::Y16, 4, 2, 0}, bytes);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("Y16 4x2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("16"), std::string::npos) << e.what();
  }
  EXPECT_THROW(convert_buffer({PixelFormat::Grey, 4, 2, 3}, std::vector<std::uint8_t>(8)), std::invalid_argument);
}

TEST(V4l2PixelFormat, SideBySideStereoSplitsIntoHalves) {
  // A 16-bit 6x2 frame: left half 1..3, right half 101..103 on every row.
  const std::vector<std::uint16_t> values{1, 2, 3, 101, 102, 103, 1, 2, 3, 101, 102, 103};
  const cv::Mat frame = convert_buffer({PixelFormat::Y12, 6, 2, 0}, words(values, 6, 12));
  const StereoPair pair = split_side_by_side(frame);
  ASSERT_EQ(pair.left.size(), cv::Size(3, 2));
  ASSERT_EQ(pair.right.size(), cv::Size(3, 2));
  EXPECT_EQ(pair.left.type(), CV_16UC1);
  for (int x = 0; x < 3; ++x) {
    EXPECT_EQ(pair.left.at<std::uint16_t>(1, x), x + 1);
    EXPECT_EQ(pair.right.at<std::uint16_t>(1, x), x + 101);
  }
  EXPECT_TRUE(pair.left.isContinuous());  // a copy, not a view into the driver's buffer
  EXPECT_THROW(split_side_by_side(cv::Mat(2, 5, CV_8UC1)), std::invalid_argument);
}

}  // namespace
}  // namespace nirslam
