#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

cv::Mat codec_noise_image(int rows, int cols, int type, std::uint64_t seed) {
  cv::Mat image(rows, cols, type);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
  return image;
}

// Smooth enough that JPEG keeps it close: a gradient with a gentle wave.
cv::Mat codec_smooth_image(int rows, int cols, int channels) {
  cv::Mat image(rows, cols, CV_8UC(channels));
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x)
      for (int c = 0; c < channels; ++c)
        image.ptr(y)[x * channels + c] = static_cast<std::uint8_t>(40 + 2 * x + y + 30 * c);
  return image;
}

bool codec_same_pixels(const cv::Mat& a, const cv::Mat& b) {
  return a.type() == b.type() && a.size() == b.size() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

fs::path codec_dir() {
  const fs::path dir = fs::temp_directory_path() / ("nirslam_image_codec_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

void codec_write_bytes(const fs::path& file, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(file, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

std::string codec_decode_error(const std::vector<std::uint8_t>& bytes) {
  try {
    decode_image(bytes);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(ImageCodec, PngRoundTripsEveryLayoutBitExactly) {
  for (const int type : {CV_8UC1, CV_16UC1, CV_8UC3, CV_16UC3, CV_8UC4, CV_16UC4}) {
    const cv::Mat image = codec_noise_image(37, 53, type, 11u + static_cast<std::uint64_t>(type));
    const cv::Mat back = decode_image(encode_png(image));
    EXPECT_TRUE(codec_same_pixels(image, back)) << cv::typeToString(type);
  }
}

TEST(ImageCodec, SixteenBitValuesAboveOneByteSurvive) {
  cv::Mat image(2, 3, CV_16UC1);
  const std::uint16_t values[] = {0, 255, 256, 1023, 40000, 65535};
  for (int i = 0; i < 6; ++i) image.at<std::uint16_t>(i / 3, i % 3) = values[i];
  for (const auto& bytes : {encode_png(image), encode_pnm(image)}) {
    const cv::Mat back = decode_image(bytes);
    ASSERT_EQ(back.type(), CV_16UC1);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(back.at<std::uint16_t>(i / 3, i % 3), values[i]);
  }
}

TEST(ImageCodec, PngKeepsBgrOrderAndStoresRgb) {
  cv::Mat blue(4, 4, CV_8UC3, cv::Scalar(255, 0, 0));  // BGR
  const std::vector<std::uint8_t> bytes = encode_png(blue);
  const cv::Mat back = decode_image(bytes);
  EXPECT_EQ(back.at<cv::Vec3b>(0, 0), cv::Vec3b(255, 0, 0));
  EXPECT_EQ(decode_image(bytes, ImageReadMode::Grey).at<std::uint8_t>(0, 0), 29);  // 0.114 * 255
}

TEST(ImageCodec, HuffmanOnlyPngRoundTripsAndEveryLevelDecodes) {
  const cv::Mat image = codec_noise_image(48, 64, CV_16UC1, 5);
  for (int level = 0; level <= 9; level += 3) {
    for (const PngStrategy strategy : {PngStrategy::Default, PngStrategy::HuffmanOnly}) {
      const cv::Mat back = decode_image(encode_png(image, {.compression_level = level, .strategy = strategy}));
      EXPECT_TRUE(codec_same_pixels(image, back)) << level;
    }
  }
  EXPECT_THROW(encode_png(image, {.compression_level = 10}), std::invalid_argument);
}

TEST(ImageCodec, PgmAndPpmRoundTrip) {
  for (const int type : {CV_8UC1, CV_16UC1, CV_8UC3, CV_16UC3}) {
    const cv::Mat image = codec_noise_image(9, 13, type, 3);
    const std::vector<std::uint8_t> bytes = encode_pnm(image);
    EXPECT_EQ(bytes[1], CV_MAT_CN(type) == 1 ? '5' : '6');
    EXPECT_TRUE(codec_same_pixels(image, decode_image(bytes))) << cv::typeToString(type);
  }
}

TEST(ImageCodec, PgmHeaderWithCommentsAndSmallMaxValue) {
  const std::string text = "P5\n# made by hand\n3 # width\n2\n15\n";
  std::vector<std::uint8_t> bytes(text.begin(), text.end());
  for (std::uint8_t v = 0; v < 6; ++v) bytes.push_back(v);
  const cv::Mat back = decode_image(bytes);
  ASSERT_EQ(back.type(), CV_8UC1);
  ASSERT_EQ(back.size(), cv::Size(3, 2));
  EXPECT_EQ(back.at<std::uint8_t>(1, 2), 5);
}

TEST(ImageCodec, JpegRoundTripStaysCloseInGreyAndColour) {
  const cv::Mat grey = codec_smooth_image(48, 64, 1);
  const cv::Mat grey_back = decode_image(encode_jpeg(grey, 95));
  ASSERT_EQ(grey_back.type(), CV_8UC1);  // a grey file stays grey as stored
  EXPECT_LT(cv::norm(grey, grey_back, cv::NORM_INF), 6.0);

  const cv::Mat colour = codec_smooth_image(48, 64, 3);
  const cv::Mat colour_back = decode_image(encode_jpeg(colour, 95));
  ASSERT_EQ(colour_back.type(), CV_8UC3);
  EXPECT_LT(cv::norm(colour, colour_back, cv::NORM_L1) / static_cast<double>(colour.total() * 3), 2.0);
  cv::Mat expected_grey;
  cv::cvtColor(colour, expected_grey, cv::COLOR_BGR2GRAY);
  EXPECT_LT(cv::norm(expected_grey, decode_image(encode_jpeg(colour, 95), ImageReadMode::Grey), cv::NORM_INF), 10.0);
}

TEST(ImageCodec, ReadModesConvertDepthAndChannels) {
  cv::Mat wide(2, 2, CV_16UC1, cv::Scalar(0x1234));
  const cv::Mat grey = decode_image(encode_png(wide), ImageReadMode::Grey);
  ASSERT_EQ(grey.type(), CV_8UC1);
  EXPECT_EQ(grey.at<std::uint8_t>(0, 0), 0x12);
  const cv::Mat bgr = decode_image(encode_png(wide), ImageReadMode::Bgr);
  ASSERT_EQ(bgr.type(), CV_8UC3);
  EXPECT_EQ(bgr.at<cv::Vec3b>(1, 1), cv::Vec3b(0x12, 0x12, 0x12));
  const cv::Mat bgra(2, 2, CV_8UC4, cv::Scalar(10, 20, 30, 40));
  EXPECT_EQ(decode_image(encode_png(bgra), ImageReadMode::Bgr).at<cv::Vec3b>(0, 0), cv::Vec3b(10, 20, 30));
}

TEST(ImageCodec, DamagedDataGivesAClearErrorNotACrash) {
  const std::vector<std::uint8_t> png = encode_png(codec_noise_image(64, 64, CV_8UC1, 1));
  const std::vector<std::uint8_t> jpeg = encode_jpeg(codec_smooth_image(64, 64, 3), 90);
  const std::vector<std::uint8_t> pgm = encode_pnm(codec_noise_image(64, 64, CV_16UC1, 2));
  for (const std::size_t keep : {std::size_t{8}, std::size_t{40}, png.size() / 2, png.size() - 5}) {
    const std::string error = codec_decode_error({png.begin(), png.begin() + static_cast<std::ptrdiff_t>(keep)});
    EXPECT_NE(error.find("PNG"), std::string::npos) << keep << ": " << error;
  }
  for (const std::size_t keep : {std::size_t{4}, std::size_t{200}, jpeg.size() / 2, jpeg.size() - 2}) {
    const std::string error = codec_decode_error({jpeg.begin(), jpeg.begin() + static_cast<std::ptrdiff_t>(keep)});
    EXPECT_NE(error.find("JPEG"), std::string::npos) << keep << ": " << error;
  }
  EXPECT_NE(codec_decode_error({pgm.begin(), pgm.end() - 1}).find("truncated"), std::string::npos);

  std::vector<std::uint8_t> flipped = png;
  flipped[flipped.size() / 2] ^= 0xff;  // inside the compressed data: a CRC or zlib error
  EXPECT_NE(codec_decode_error(flipped), "");

  cv::RNG rng(7);
  std::vector<std::uint8_t> noise(4096);
  for (auto& b : noise) b = static_cast<std::uint8_t>(rng.uniform(0, 256));
  noise[0] = 'x';
  EXPECT_NE(codec_decode_error(noise).find("not a PNG, JPEG"), std::string::npos);
  // Valid signatures followed by noise.
  for (const std::vector<std::uint8_t>& head : {std::vector<std::uint8_t>(png.begin(), png.begin() + 8),
                                               std::vector<std::uint8_t>(jpeg.begin(), jpeg.begin() + 3),
                                               std::vector<std::uint8_t>{'P', '5', '\n'}}) {
    std::vector<std::uint8_t> bytes = head;
    bytes.insert(bytes.end(), noise.begin() + 1, noise.end());
    EXPECT_NE(codec_decode_error(bytes), "");
  }
  EXPECT_NE(codec_decode_error({}), "");
}

TEST(ImageCodec, FileErrorsNameTheFile) {
  const fs::path dir = codec_dir();
  const fs::path missing = dir / "no_such_frame.png";
  try {
    read_image(missing);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_frame.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos) << e.what();
  }
  const fs::path empty = dir / "empty.png";
  codec_write_bytes(empty, {});
  try {
    read_image(empty);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("empty.png: image file is empty"), std::string::npos) << e.what();
  }
  try {
    read_image(dir);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is a folder"), std::string::npos) << e.what();
  }
  const fs::path cut = dir / "cut.jpg";
  const std::vector<std::uint8_t> jpeg = encode_jpeg(codec_smooth_image(32, 32, 1), 90);
  codec_write_bytes(cut, {jpeg.begin(), jpeg.begin() + static_cast<std::ptrdiff_t>(jpeg.size() / 2)});
  try {
    read_image(cut);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.jpg: cannot decode image"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(ImageCodec, WriteImagePicksTheFormatFromTheExtension) {
  const fs::path dir = codec_dir();
  const cv::Mat grey = codec_noise_image(20, 30, CV_8UC1, 9);
  for (const char* name : {"a.png", "b.PGM", "c.pnm"}) {
    write_image(dir / name, grey);
    EXPECT_TRUE(codec_same_pixels(grey, read_image(dir / name))) << name;
  }
  write_image(dir / "d.jpg", codec_smooth_image(20, 30, 1), {.png = {}, .jpeg_quality = 90});
  EXPECT_EQ(read_image(dir / "d.jpg").type(), CV_8UC1);
  const cv::Mat colour = codec_noise_image(20, 30, CV_8UC3, 4);
  write_image(dir / "e.ppm", colour);
  EXPECT_TRUE(codec_same_pixels(colour, read_image(dir / "e.ppm")));

  EXPECT_THROW(write_image(dir / "f.bmp", grey), std::runtime_error);
  EXPECT_THROW(write_image(dir / "g.pgm", colour), std::runtime_error);
  EXPECT_THROW(write_image(dir / "h.jpg", codec_noise_image(4, 4, CV_16UC1, 1)), std::runtime_error);
  EXPECT_THROW(write_image(dir / "i.png", cv::Mat(4, 4, CV_32FC1)), std::runtime_error);
  try {
    write_image(dir / "no_such_folder" / "j.png", grey);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("j.png: cannot write image (No such file"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace nirslam
