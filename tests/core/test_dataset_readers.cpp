// Dataset readers: TUM monoVO (images/ and images.zip), EuRoC (the real micro sequence) and plain
// image folders. Fixtures are written at run time into a fresh temporary folder per test.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <zip.h>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/sources/euroc_reader.hpp"
#include "nirslam/sources/image_folder_reader.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"
#include "core/euroc_micro.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

// A fresh folder for one test, removed afterwards.
class ReaderTest : public ::testing::Test {
protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("nirslam_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" +
             std::to_string(std::random_device{}()));
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path root_;
};

void write_text(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  std::ofstream out(file, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << file;
}

// Random content, so a frame that comes back in the wrong order or shifted is caught.
cv::Mat random_image(int width, int height, int type, unsigned seed) {
  cv::Mat image(height, width, type);
  cv::theRNG().state = seed;
  cv::randu(image, 0, type == CV_16UC1 ? 65536 : 256);
  return image;
}

void save_dataset_image(const fs::path& file, const cv::Mat& image) {
  fs::create_directories(file.parent_path());
  ASSERT_NO_THROW(nirslam::write_image(file, image)) << file;
}

// images.zip holding `images` as PNG members named `names`, written with libzip.
void write_zip(const fs::path& file, const std::vector<std::string>& names,
               const std::vector<cv::Mat>& images) {
  int error = 0;
  zip_t* archive = zip_open(file.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
  ASSERT_NE(archive, nullptr) << "zip_open error " << error;
  std::vector<std::vector<unsigned char>> encoded(images.size());  // alive until zip_close
  for (std::size_t i = 0; i < images.size(); ++i) {
    ASSERT_NO_THROW(encoded[i] = encode_png(images[i]));
    zip_source_t* source = zip_source_buffer(archive, encoded[i].data(), encoded[i].size(), 0);
    ASSERT_NE(source, nullptr);
    ASSERT_GE(zip_file_add(archive, names[i].c_str(), source, ZIP_FL_OVERWRITE), 0);
  }
  ASSERT_EQ(zip_close(archive), 0);
}

bool same_pixels(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

// The message of the InputError that `action` throws; fails the test if it throws nothing.
template <typename Action>
std::string input_error(Action&& action) {
  try {
    action();
  } catch (const InputError& error) {
    return error.what();
  }
  ADD_FAILURE() << "expected an InputError";
  return {};
}

#define EXPECT_CONTAINS(text, part)                                              \
  EXPECT_NE(std::string(text).find(part), std::string::npos)                     \
      << "'" << (text) << "' does not contain '" << (part) << "'"

// ---------------------------------------------------------------------------------------------
// TUM monoVO

class TumMonoVo : public ReaderTest {
protected:
  // A TUM monoVO folder with `count` frames of 64x48 and a pinhole camera.txt.
  std::vector<cv::Mat> make_sequence(int count, int type, bool zip) {
    std::vector<cv::Mat> images;
    std::vector<std::string> names;
    std::string times;
    for (int i = 0; i < count; ++i) {
      char name[16];
      std::snprintf(name, sizeof name, "%05d.png", i);
      names.emplace_back(name);
      images.push_back(random_image(64, 48, type, 100u + static_cast<unsigned>(i)));
      if (!zip) save_dataset_image(root_ / "images" / name, images.back());
      times += std::string(name, 5) + " " + std::to_string(1000.0 + 0.05 * i) + " " +
               std::to_string(5.0 + i) + "\n";
    }
    if (zip) write_zip(root_ / "images.zip", names, images);
    write_text(root_ / "times.txt", times);
    write_text(root_ / "camera.txt", "Pinhole 50 50 31.5 23.5 0\n64 48\nnone\n64 48\n");
    return images;
  }
};

TEST_F(TumMonoVo, ReadsFramesWithTimesExposuresAndCamera) {
  const std::vector<cv::Mat> images = make_sequence(5, CV_8UC1, false);
  write_text(root_ / "pcalib.txt", "0 1 2\n");
  save_dataset_image(root_ / "vignette.png", cv::Mat(48, 64, CV_16UC1, cv::Scalar(60000)));
  TumMonoVoReader reader(root_);
  EXPECT_EQ(reader.info().kind, "tum");
  EXPECT_EQ(reader.info().frame_count, 5u);
  EXPECT_FALSE(reader.info().live);
  EXPECT_NEAR(reader.info().nominal_fps, 20.0, 1e-9);
  ASSERT_NE(reader.camera(), nullptr);
  EXPECT_EQ(reader.camera()->type(), CameraModelType::Pinhole);
  EXPECT_EQ(reader.response_file(), root_ / "pcalib.txt");
  EXPECT_EQ(reader.vignette_file(), root_ / "vignette.png");
  EXPECT_FALSE(reader.reads_zip());
  for (int pass = 0; pass < 2; ++pass) {  // the second pass after rewind() repeats the first
    for (int i = 0; i < 5; ++i) {
      const std::optional<Frame> frame = reader.next();
      ASSERT_TRUE(frame.has_value());
      EXPECT_TRUE(same_pixels(frame->image, images[static_cast<std::size_t>(i)])) << i;
      EXPECT_EQ(frame->bit_depth, 8);
      EXPECT_EQ(frame->index, i);
      EXPECT_DOUBLE_EQ(frame->timestamp_s, 1000.0 + 0.05 * i);
      ASSERT_TRUE(frame->exposure_ms.has_value());
      EXPECT_DOUBLE_EQ(*frame->exposure_ms, 5.0 + i);
      char name[16];
      std::snprintf(name, sizeof name, "%05d.png", i);
      EXPECT_EQ(frame->name, name);
      EXPECT_NO_THROW(validate_frame(*frame, "tum frame"));
    }
    EXPECT_FALSE(reader.next().has_value());
    reader.rewind();
  }
}

TEST_F(TumMonoVo, ReadsImagesLazily) {
  make_sequence(4, CV_8UC1, false);
  TumMonoVoReader reader(root_);
  fs::remove(root_ / "images" / "00002.png");  // after opening: only reading frame 2 can notice
  EXPECT_TRUE(reader.next().has_value());
  EXPECT_TRUE(reader.next().has_value());
  const std::string message = input_error([&] { reader.next(); });
  EXPECT_CONTAINS(message, "00002.png");
  EXPECT_CONTAINS(message, "missing");
  EXPECT_TRUE(reader.next().has_value());  // the stream moves on past the bad frame
}

TEST_F(TumMonoVo, SixteenBitFramesKeepTheirDepth) {
  const std::vector<cv::Mat> images = make_sequence(3, CV_16UC1, false);
  TumMonoVoReader reader(root_);
  for (const cv::Mat& image : images) {
    const std::optional<Frame> frame = reader.next();
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->image.type(), CV_16UC1);
    EXPECT_EQ(frame->bit_depth, 16);
    EXPECT_TRUE(same_pixels(frame->image, image));
    double max_value = 0.0;
    cv::minMaxLoc(frame->image, nullptr, &max_value);
    EXPECT_GT(max_value, 255.0);
  }
}

TEST_F(TumMonoVo, ReadsImagesZip) {
  const std::vector<cv::Mat> images = make_sequence(6, CV_8UC1, true);
  ASSERT_FALSE(fs::exists(root_ / "images"));
  TumMonoVoReader reader(root_);
  EXPECT_TRUE(reader.reads_zip());
  EXPECT_EQ(reader.info().frame_count, 6u);
  for (std::size_t i = 0; i < images.size(); ++i) {
    const std::optional<Frame> frame = reader.next();
    ASSERT_TRUE(frame.has_value());
    EXPECT_TRUE(same_pixels(frame->image, images[i])) << i;
    EXPECT_EQ(frame->index, static_cast<std::int64_t>(i));
    EXPECT_DOUBLE_EQ(*frame->exposure_ms, 5.0 + static_cast<double>(i));
  }
  EXPECT_FALSE(reader.next().has_value());
  reader.rewind();
  EXPECT_TRUE(same_pixels(reader.next()->image, images[0]));
  // Jumps (the GUI's seek bar): a member read out of order, and a refused jump keeps the place.
  EXPECT_TRUE(reader.info().seekable);
  reader.seek(4);
  const std::optional<Frame> fifth = reader.next();
  ASSERT_TRUE(fifth.has_value());
  EXPECT_EQ(fifth->index, 4);
  EXPECT_TRUE(same_pixels(fifth->image, images[4]));
  EXPECT_DOUBLE_EQ(*fifth->exposure_ms, 9.0);
  try {
    reader.seek(6);
    ADD_FAILURE() << "frame 6 of 6 is past the end";
  } catch (const std::out_of_range& e) {
    EXPECT_CONTAINS(std::string(e.what()), "cannot seek to frame 6, the sequence has 6 frames");
  }
  EXPECT_EQ(reader.next()->index, 5);
}

TEST_F(TumMonoVo, CorruptZipMemberNamesTheMember) {
  make_sequence(2, CV_8UC1, false);
  // A zip whose second member is not an image.
  int error = 0;
  zip_t* archive = zip_open((root_ / "images.zip").c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
  ASSERT_NE(archive, nullptr);
  const std::vector<unsigned char> good = encode_png(random_image(64, 48, CV_8UC1, 1));
  const std::string garbage = "definitely not a PNG";
  zip_file_add(archive, "00000.png", zip_source_buffer(archive, good.data(), good.size(), 0), 0);
  zip_file_add(archive, "00001.png",
               zip_source_buffer(archive, garbage.data(), garbage.size(), 0), 0);
  ASSERT_EQ(zip_close(archive), 0);
  fs::remove_all(root_ / "images");
  TumMonoVoReader reader(root_);
  EXPECT_TRUE(reader.next().has_value());
  const std::string message = input_error([&] { reader.next(); });
  EXPECT_CONTAINS(message, "images.zip/00001.png");
  EXPECT_CONTAINS(message, "cannot decode");
  // Not a zip at all.
  write_text(root_ / "images.zip", "PK? no");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader bad(root_); }), "cannot open zip archive");
}

TEST_F(TumMonoVo, ColourImagesBecomeGrey) {
  make_sequence(2, CV_8UC1, false);
  const cv::Mat colour = random_image(64, 48, CV_8UC3, 5);
  save_dataset_image(root_ / "images" / "00001.png", colour);
  TumMonoVoReader reader(root_);
  reader.next();
  const std::optional<Frame> frame = reader.next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->image.type(), CV_8UC1);
  cv::Mat expected;
  cv::cvtColor(colour, expected, cv::COLOR_BGR2GRAY);
  EXPECT_TRUE(same_pixels(frame->image, expected));
}

TEST_F(TumMonoVo, BadTimesLineNamesTheLine) {
  make_sequence(4, CV_8UC1, false);
  write_text(root_ / "times.txt",
             "00000 1000.0 5\n00001 1000.05 5\n00002 1000.1O 5\n00003 1000.15 5\n");
  const std::string message = input_error([&] { TumMonoVoReader reader(root_); });
  EXPECT_CONTAINS(message, "times.txt:3");
  EXPECT_CONTAINS(message, "1000.1O");

  write_text(root_ / "times.txt", "00000 1000.0 5\n00001 1000.05 -5\n00002 1000.1\n00003 1000.15\n");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_); }), "times.txt:2: exposure");
  write_text(root_ / "times.txt", "00000 1000.0\n00001 999.0\n00002 1000.1\n00003 1000.15\n");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_); }), "times.txt:2: timestamp goes");
  write_text(root_ / "times.txt", "00000 1000.0\n00001\n00002 1000.1\n00003 1000.15\n");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_); }), "times.txt:2");
  write_text(root_ / "times.txt", "00000 1000.0 1 2\n");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_); }), "times.txt:1");
  // Exposure is optional per line; comments and blank lines are skipped.
  write_text(root_ / "times.txt", "# id t exp\n00000 1000.0\n\n00001 1000.05 4\n00002 1000.1\n"
                                  "00003 1000.15 3.5\n");
  TumMonoVoReader reader(root_);
  EXPECT_FALSE(reader.next()->exposure_ms.has_value());
  EXPECT_DOUBLE_EQ(*reader.next()->exposure_ms, 4.0);
}

TEST_F(TumMonoVo, IlluminatorPowerFromFramesCsv) {
  make_sequence(3, CV_8UC1, false);
  // Without frames.csv (a TUM dataset) the power is unknown.
  EXPECT_FALSE(TumMonoVoReader(root_).next()->illuminator_power_w.has_value());
  EXPECT_FALSE(TumMonoVoReader(root_).info().reports_lamp_power);
  // The simulator's layout; a frame the file does not list keeps it unknown.
  write_text(root_ / "frames.csv",
             "index,file,timestamp_s,exposure_ms,gain,illuminator_power_w,mean_grey\n"
             "0,images/00000.png,1000.0,5,1,20.0,0.4\n2,images/00002.png,1000.1,7,1,0,0.3\n");
  TumMonoVoReader reader(root_);
  EXPECT_TRUE(reader.info().reports_lamp_power);
  EXPECT_DOUBLE_EQ(*reader.next()->illuminator_power_w, 20.0);
  EXPECT_FALSE(reader.next()->illuminator_power_w.has_value());
  EXPECT_DOUBLE_EQ(*reader.next()->illuminator_power_w, 0.0);
  // The lamp off in every frame: powers reported, none lights the frames.
  write_text(root_ / "frames.csv", "file,illuminator_power_w\nimages/00000.png,0\nimages/00001.png,0\n");
  EXPECT_FALSE(TumMonoVoReader(root_).info().reports_lamp_power);
  // A frames.csv of another kind (no power column) is not an error.
  write_text(root_ / "frames.csv", "id,note\n0,anything\n");
  EXPECT_FALSE(TumMonoVoReader(root_).next()->illuminator_power_w.has_value());
  // A bad power or a short line names the file and line.
  write_text(root_ / "frames.csv", "file,illuminator_power_w\nimages/00000.png,20\nimages/00001.png,-3\n");
  const std::string message = input_error([&] { TumMonoVoReader bad(root_); });
  EXPECT_CONTAINS(message, "frames.csv:3");
  EXPECT_CONTAINS(message, "-3");
  write_text(root_ / "frames.csv", "file,illuminator_power_w\nimages/00000.png\n");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader bad(root_); }), "frames.csv:2");
}

TEST_F(TumMonoVo, CountMismatchNamesBothCounts) {
  make_sequence(4, CV_8UC1, false);
  write_text(root_ / "times.txt", "00000 1000.0\n00001 1000.05\n00002 1000.1\n");
  const std::string message = input_error([&] { TumMonoVoReader reader(root_); });
  EXPECT_CONTAINS(message, "times.txt");
  EXPECT_CONTAINS(message, "3 timestamp lines");
  EXPECT_CONTAINS(message, "4 images");
}

TEST_F(TumMonoVo, IdsMustMatchNumberedImages) {
  make_sequence(3, CV_8UC1, false);
  write_text(root_ / "times.txt", "00000 1000.0\n00002 1000.05\n00003 1000.1\n");
  const std::string message = input_error([&] { TumMonoVoReader reader(root_); });
  EXPECT_CONTAINS(message, "times.txt:2");
  EXPECT_CONTAINS(message, "00001.png");
}

TEST_F(TumMonoVo, ImageOfWrongSizeNamesTheFile) {
  make_sequence(3, CV_8UC1, false);
  save_dataset_image(root_ / "images" / "00001.png", random_image(48, 64, CV_8UC1, 9));
  {
    TumMonoVoReader reader(root_);
    reader.next();
    const std::string message = input_error([&] { reader.next(); });
    EXPECT_CONTAINS(message, "00001.png");
    EXPECT_CONTAINS(message, "48x64");
    EXPECT_CONTAINS(message, "camera.txt says 64x48");
  }
  // Without camera.txt the first frame sets the size.
  fs::remove(root_ / "camera.txt");
  TumMonoVoReader reader(root_);
  EXPECT_EQ(reader.camera(), nullptr);
  reader.next();
  EXPECT_CONTAINS(input_error([&] { reader.next(); }), "the first frame");
}

TEST_F(TumMonoVo, MixedDepthsAreAnError) {
  make_sequence(2, CV_8UC1, false);
  save_dataset_image(root_ / "images" / "00001.png", random_image(64, 48, CV_16UC1, 3));
  TumMonoVoReader reader(root_);
  reader.next();
  const std::string message = input_error([&] { reader.next(); });
  EXPECT_CONTAINS(message, "00001.png");
  EXPECT_CONTAINS(message, "16-bit");
}

TEST_F(TumMonoVo, CorruptImageNamesTheFile) {
  make_sequence(3, CV_8UC1, false);
  write_text(root_ / "images" / "00002.png", "\x89PNG\r\n\x1a\n truncated");
  TumMonoVoReader reader(root_);
  reader.next();
  reader.next();
  const std::string message = input_error([&] { reader.next(); });
  EXPECT_CONTAINS(message, "00002.png");
  EXPECT_CONTAINS(message, "cannot decode");
  write_text(root_ / "images" / "00002.png", "");
  reader.rewind();
  reader.next();
  reader.next();
  EXPECT_CONTAINS(input_error([&] { reader.next(); }), "empty");
}

TEST_F(TumMonoVo, MissingPartsAreNamed) {
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_ / "nope"); }), "does not exist");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_); }), "neither images/");
  make_sequence(2, CV_8UC1, false);
  fs::remove(root_ / "times.txt");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_); }), "times.txt: missing");
  make_sequence(2, CV_8UC1, false);
  // camera.txt without its output size line.
  write_text(root_ / "camera.txt", "Pinhole 50 50 31.5 23.5 0\n64 48\nnone\n");
  const std::string message = input_error([&] { TumMonoVoReader reader(root_); });
  EXPECT_CONTAINS(message, "camera.txt:4");
  EXPECT_CONTAINS(message, "output size");
  fs::remove_all(root_ / "images");
  fs::create_directories(root_ / "images");
  EXPECT_CONTAINS(input_error([&] { TumMonoVoReader reader(root_); }), "holds no image files");
}

// ---------------------------------------------------------------------------------------------
// EuRoC

// data.csv read independently of the reader: (timestamp_ns, filename) pairs.
std::vector<std::pair<std::int64_t, std::string>> read_euroc_csv(const fs::path& csv) {
  std::vector<std::pair<std::int64_t, std::string>> rows;
  std::ifstream in(csv);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t comma = line.find(',');
    std::string name = line.substr(comma + 1);
    if (!name.empty() && name.back() == '\r') name.pop_back();
    rows.emplace_back(std::stoll(line.substr(0, comma)), name);
  }
  return rows;
}

TEST(Euroc, ReadsTheRealMicroSequence) {
  EurocReader reader(kEurocMicro);
  const auto rows = read_euroc_csv(kEurocMicro / "mav0/cam0/data.csv");
  ASSERT_EQ(rows.size(), 95u);
  EXPECT_EQ(reader.info().kind, "euroc");
  EXPECT_EQ(reader.info().frame_count, 95u);
  EXPECT_DOUBLE_EQ(reader.info().nominal_fps, 20.0);
  ASSERT_NE(reader.camera(), nullptr);
  EXPECT_EQ(reader.camera()->type(), CameraModelType::RadTan);
  EXPECT_DOUBLE_EQ(reader.camera()->fx(), 458.654);
  EXPECT_DOUBLE_EQ(reader.camera()->fy(), 457.296);
  EXPECT_DOUBLE_EQ(reader.camera()->cx(), 367.215);
  EXPECT_DOUBLE_EQ(reader.camera()->cy(), 248.375);
  EXPECT_DOUBLE_EQ(reader.camera()->distortion()[0], -0.28340811);
  ASSERT_TRUE(reader.sensor().has_value());
  EXPECT_DOUBLE_EQ(reader.sensor()->T_body_sensor(1, 0), 0.999557249008);

  std::size_t count = 0;
  double previous = 0.0;
  while (const std::optional<Frame> frame = reader.next()) {
    ASSERT_LT(count, rows.size());
    EXPECT_EQ(frame->image.size(), cv::Size(752, 480));
    EXPECT_EQ(frame->image.type(), CV_8UC1);
    EXPECT_EQ(frame->bit_depth, 8);
    EXPECT_EQ(frame->index, static_cast<std::int64_t>(count));
    EXPECT_EQ(frame->name, rows[count].second);
    EXPECT_EQ(reader.timestamps_ns()[count], rows[count].first);
    // Seconds to the precision a double has at 1.4e9 s (2.4e-7 s).
    const double expected = static_cast<double>(rows[count].first / 1000000000) +
                            static_cast<double>(rows[count].first % 1000000000) * 1e-9;
    EXPECT_NEAR(frame->timestamp_s, expected, 5e-7);
    if (count > 0) {
      EXPECT_NEAR(frame->timestamp_s - previous, 0.05, 1e-5);  // 20 Hz
    }
    previous = frame->timestamp_s;
    if (count == 0 || count == 94) {
      const cv::Mat direct =
          nirslam::read_image(kEurocMicro / "mav0/cam0/data" / rows[count].second);
      EXPECT_TRUE(same_pixels(frame->image, direct));
    }
    ++count;
  }
  EXPECT_EQ(count, 95u);
  EXPECT_NEAR(seconds_from_nanoseconds(reader.timestamps_ns().front()), 1403715273.262143, 1e-6);
  EXPECT_TRUE(reader.info().seekable);
  reader.seek(94);
  const std::optional<Frame> last = reader.next();
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->index, 94);
  EXPECT_EQ(last->name, rows[94].second);
  EXPECT_FALSE(reader.next().has_value());
}

TEST(Euroc, AcceptsRootMav0OrCameraFolder) {
  for (const fs::path& path : {kEurocMicro, kEurocMicro / "mav0", kEurocMicro / "mav0" / "cam0"}) {
    EurocReader reader(path);
    EXPECT_EQ(reader.camera_folder().lexically_normal(), (kEurocMicro / "mav0/cam0").lexically_normal())
        << path;
    EXPECT_EQ(reader.info().frame_count, 95u);
  }
  EXPECT_CONTAINS(input_error([] { EurocReader reader(kEurocMicro / "mav0" / "cam0" / "data"); }),
                  "not a EuRoC folder");
  EXPECT_CONTAINS(input_error([] { EurocReader reader(kEurocMicro, EurocOptions{"cam1"}); }),
                  "mav0/cam1/data.csv");
}

TEST(Euroc, NanosecondsToSecondsKeepsEveryDigitADoubleHas) {
  EXPECT_EQ(seconds_from_nanoseconds(1'500'000'000), 1.5);
  EXPECT_EQ(seconds_from_nanoseconds(0), 0.0);
  EXPECT_NEAR(seconds_from_nanoseconds(-1), -1e-9, 1e-18);
  EXPECT_EQ(seconds_from_nanoseconds(-1'500'000'000), -1.5);
  // The nearest double to 1403715273.262142976 s.
  EXPECT_EQ(seconds_from_nanoseconds(1403715273262142976), 1403715273.262142976);
  // Frame spacing survives the conversion: 50.000128 ms.
  const double dt = seconds_from_nanoseconds(1403715273312143104) -
                    seconds_from_nanoseconds(1403715273262142976);
  EXPECT_NEAR(dt, 0.050000128, 2.5e-7);
}

class EurocFixture : public ReaderTest {
protected:
  // mav0/cam0 with three 32x24 images and `csv` as data.csv.
  void make(const std::string& csv) {
    const fs::path cam = root_ / "mav0" / "cam0";
    for (const char* name : {"100.png", "200.png", "300.png"})
      save_dataset_image(cam / "data" / name, random_image(32, 24, CV_8UC1, 4));
    write_text(cam / "data.csv", csv);
  }
};

TEST_F(EurocFixture, MalformedDataCsvNamesTheLine) {
  make("#timestamp [ns],filename\n100,100.png\n2OO,200.png\n300,300.png\n");
  std::string message = input_error([&] { EurocReader reader(root_); });
  EXPECT_CONTAINS(message, "data.csv:3");
  EXPECT_CONTAINS(message, "2OO");
  make("#timestamp [ns],filename\n100,100.png\n200,250.png\n");
  message = input_error([&] { EurocReader reader(root_); });
  EXPECT_CONTAINS(message, "data.csv:3");
  EXPECT_CONTAINS(message, "250.png");
  make("#timestamp [ns],filename\n200,200.png\n100,100.png\n");
  EXPECT_CONTAINS(input_error([&] { EurocReader reader(root_); }), "data.csv:3: timestamp is not after");
  make("#timestamp [ns],filename\n100;100.png\n");
  EXPECT_CONTAINS(input_error([&] { EurocReader reader(root_); }), "data.csv:2");
  make("#timestamp [ns],filename\n");
  EXPECT_CONTAINS(input_error([&] { EurocReader reader(root_); }), "lists no images");
}

TEST_F(EurocFixture, WithoutSensorYamlThereIsNoCamera) {
  make("#timestamp [ns],filename\r\n100,100.png\r\n200,200.png\r\n300,300.png\r\n");
  EurocReader reader(root_ / "mav0");
  EXPECT_EQ(reader.camera(), nullptr);
  EXPECT_NEAR(reader.info().nominal_fps, 1e7, 1.0);  // 100 ns apart
  int count = 0;
  while (const auto frame = reader.next()) {
    EXPECT_NEAR(frame->timestamp_s, (count + 1) * 1e-7, 1e-15);
    ++count;
  }
  EXPECT_EQ(count, 3);
}

TEST_F(EurocFixture, ImageOfAnotherSizeThanSensorYaml) {
  make("#timestamp [ns],filename\n100,100.png\n200,200.png\n300,300.png\n");
  fs::copy_file(kEurocMicro / "mav0/cam0/sensor.yaml", root_ / "mav0/cam0/sensor.yaml");
  EurocReader reader(root_);
  const std::string message = input_error([&] { reader.next(); });
  EXPECT_CONTAINS(message, "100.png");
  EXPECT_CONTAINS(message, "image is 32x24");
  EXPECT_CONTAINS(message, "sensor.yaml says 752x480");
}

// ---------------------------------------------------------------------------------------------
// Image folders

TEST(NaturalOrder, NumbersCompareByValue) {
  EXPECT_TRUE(natural_less("img2.png", "img10.png"));
  EXPECT_FALSE(natural_less("img10.png", "img2.png"));
  EXPECT_TRUE(natural_less("0009.png", "10.png"));
  EXPECT_TRUE(natural_less("a.png", "b.png"));
  EXPECT_TRUE(natural_less("frame_1_2.png", "frame_1_10.png"));
  EXPECT_TRUE(natural_less("img.png", "img1.png"));
  EXPECT_TRUE(natural_less("x99", "x100"));
  EXPECT_FALSE(natural_less("x100", "x100"));
  // Equal values spelled differently still get a strict, consistent order.
  EXPECT_NE(natural_less("01.png", "1.png"), natural_less("1.png", "01.png"));
  EXPECT_TRUE(natural_less("1403715273262142976.png", "1403715273312143104.png"));
  EXPECT_TRUE(natural_less("9999999999999999999999.png", "10000000000000000000000.png"));
}

class ImageFolder : public ReaderTest {};

TEST_F(ImageFolder, NaturalOrderAndNominalRate) {
  const std::vector<std::string> names = {"img1.png", "img2.png", "img10.png", "img11.png"};
  std::vector<cv::Mat> images;
  for (std::size_t i = 0; i < names.size(); ++i) {
    images.push_back(random_image(40, 30, CV_8UC1, 50u + static_cast<unsigned>(i)));
    save_dataset_image(root_ / names[i], images.back());
  }
  write_text(root_ / "notes.md", "not an image");
  fs::create_directories(root_ / "sub.png");  // a folder, even with an image-like name
  {
    ImageFolderReader reader(root_);
    EXPECT_EQ(reader.info().kind, "folder");
    EXPECT_EQ(reader.info().frame_count, 4u);
    EXPECT_DOUBLE_EQ(reader.info().nominal_fps, 20.0);
    EXPECT_FALSE(reader.has_recorded_timestamps());
    EXPECT_EQ(reader.camera(), nullptr);
    for (std::size_t i = 0; i < names.size(); ++i) {
      const std::optional<Frame> frame = reader.next();
      ASSERT_TRUE(frame.has_value());
      EXPECT_EQ(frame->name, names[i]);
      EXPECT_TRUE(same_pixels(frame->image, images[i]));
      EXPECT_DOUBLE_EQ(frame->timestamp_s, static_cast<double>(i) / 20.0);
      EXPECT_FALSE(frame->exposure_ms.has_value());
    }
    EXPECT_FALSE(reader.next().has_value());
    EXPECT_TRUE(reader.info().seekable);
    reader.seek(2);
    const std::optional<Frame> third = reader.next();
    ASSERT_TRUE(third.has_value());
    EXPECT_EQ(third->name, "img10.png");
    EXPECT_EQ(third->index, 2);
    EXPECT_DOUBLE_EQ(third->timestamp_s, 0.1);
    EXPECT_THROW(reader.seek(4), std::out_of_range);
  }
  ImageFolderOptions options;
  options.nominal_fps = 10.0;
  ImageFolderReader slow(root_, options);
  slow.next();
  EXPECT_DOUBLE_EQ(slow.next()->timestamp_s, 0.1);
  options.nominal_fps = 0.0;
  EXPECT_THROW(ImageFolderReader(root_, options), std::invalid_argument);
}

TEST_F(ImageFolder, TumStyleTimesFile) {
  for (int i = 0; i < 3; ++i) {
    // Appended, not "f" + std::to_string(i): GCC 12 at -O3 reports a false -Wrestrict inside the
    // inlined operator+(const char*, std::string&&) in a unity batch.
    std::string name = "f";
    name += std::to_string(i);
    name += ".png";
    save_dataset_image(root_ / name, random_image(40, 30, CV_8UC1, 1));
  }
  write_text(root_ / "times.txt", "0 5.0 2.5\n1 5.5 3.0\n2 6.0\n");
  ImageFolderReader reader(root_);
  EXPECT_TRUE(reader.has_recorded_timestamps());
  EXPECT_DOUBLE_EQ(reader.info().nominal_fps, 2.0);
  EXPECT_DOUBLE_EQ(reader.next()->exposure_ms.value(), 2.5);
  const std::optional<Frame> second = reader.next();
  EXPECT_DOUBLE_EQ(second->timestamp_s, 5.5);
  EXPECT_FALSE(reader.next()->exposure_ms.has_value());

  write_text(root_ / "times.txt", "0 5.0\n1 5.5\n");
  const std::string message = input_error([&] { ImageFolderReader bad(root_); });
  EXPECT_CONTAINS(message, "2 timestamp lines");
  EXPECT_CONTAINS(message, "3 images");
}

TEST_F(ImageFolder, FileNameTimesFile) {
  for (const char* name : {"b2.png", "b10.png", "b1.png"})
    save_dataset_image(root_ / name, random_image(40, 30, CV_8UC1, 1));
  ImageFolderOptions options;
  options.times_file = root_ / "stamps.txt";
  write_text(root_ / "stamps.txt", "b10.png 3.0\nb1.png 1.0\nb2.png 2.0\n");
  ImageFolderReader reader(root_, options);
  EXPECT_EQ(reader.next()->timestamp_s, 1.0);
  EXPECT_EQ(reader.next()->timestamp_s, 2.0);
  const std::optional<Frame> third = reader.next();
  EXPECT_EQ(third->timestamp_s, 3.0);
  EXPECT_EQ(third->name, "b10.png");

  write_text(root_ / "stamps.txt", "b10.png 3.0\nb1.png 1.0\nb3.png 2.0\n");
  EXPECT_CONTAINS(input_error([&] { ImageFolderReader bad(root_, options); }), "stamps.txt:3");
  write_text(root_ / "stamps.txt", "b10.png 3.0\nb1.png 1.0\n");
  EXPECT_CONTAINS(input_error([&] { ImageFolderReader bad(root_, options); }),
                  "no timestamp for image b2.png");
  write_text(root_ / "stamps.txt", "b10.png 3.0\nb1.png 1.0\nb2.png 4.0\n");
  EXPECT_CONTAINS(input_error([&] { ImageFolderReader bad(root_, options); }), "earlier");
  write_text(root_ / "stamps.txt", "b10.png 3.0\n7 1.0\nb2.png 2.0\n");
  EXPECT_CONTAINS(input_error([&] { ImageFolderReader bad(root_, options); }), "stamps.txt:2: mixes");
}

TEST_F(ImageFolder, CameraFileBesideTheImagesChecksTheirSize) {
  save_dataset_image(root_ / "a.png", random_image(40, 30, CV_8UC1, 1));
  write_text(root_ / "camera.txt", "Pinhole 50 50 19.5 14.5 0\n40 30\nnone\n40 30\n");
  ImageFolderReader reader(root_);
  ASSERT_NE(reader.camera(), nullptr);
  EXPECT_EQ(reader.camera()->width(), 40);
  EXPECT_TRUE(reader.next().has_value());
  write_text(root_ / "camera.txt", "Pinhole 50 50 19.5 14.5 0\n41 30\nnone\n41 30\n");
  ImageFolderReader mismatched(root_);
  EXPECT_CONTAINS(input_error([&] { mismatched.next(); }), "a.png");
}

TEST_F(ImageFolder, EmptyOrMissingFolder) {
  EXPECT_CONTAINS(input_error([&] { ImageFolderReader reader(root_); }), "no image files");
  EXPECT_CONTAINS(input_error([&] { ImageFolderReader reader(root_ / "absent"); }), "does not exist");
  write_text(root_ / "x.png", "");
  EXPECT_CONTAINS(input_error([&] { ImageFolderReader reader(root_ / "x.png"); }), "is not a folder");
}

}  // namespace
}  // namespace nirslam
