// open_source: the right reader for each layout, and a clear error for anything else.

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/sources/open_source.hpp"
#include "core/euroc_micro.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

class OpenSource : public ::testing::Test {
protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("nirslam_open_source_" + std::string(info->name()) + "_" +
             std::to_string(std::random_device{}()));
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  void write_image(const fs::path& file) {
    fs::create_directories(file.parent_path());
    ASSERT_NO_THROW(nirslam::write_image(file, cv::Mat(24, 32, CV_8UC1, cv::Scalar(7))));
  }

  // The InputError message open_source throws for `path`.
  static std::string open_error(const fs::path& path) {
    try {
      open_source(path);
    } catch (const InputError& error) {
      EXPECT_EQ(error.file(), path);
      return error.what();
    }
    ADD_FAILURE() << "no InputError for " << path;
    return {};
  }

  fs::path root_;
};

TEST_F(OpenSource, RealEurocFromRootMav0OrCamera) {
  for (const fs::path& path : {kEurocMicro, kEurocMicro / "mav0", kEurocMicro / "mav0/cam0"}) {
    EXPECT_EQ(detect_source_format(path), SourceFormat::Euroc) << path;
    const std::unique_ptr<Source> source = open_source(path);
    EXPECT_EQ(source->info().kind, "euroc");
    EXPECT_EQ(source->info().frame_count, 95u);
    ASSERT_NE(source->camera(), nullptr);
    const std::optional<Frame> frame = source->next();
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->image.cols, 752);
  }
}

TEST_F(OpenSource, TumMonoVoFolder) {
  write_image(root_ / "images" / "00000.png");
  write_image(root_ / "images" / "00001.png");
  std::ofstream(root_ / "times.txt") << "00000 1.0 3.0\n00001 1.1 3.0\n";
  std::ofstream(root_ / "camera.txt") << "Pinhole 30 30 15.5 11.5 0\n32 24\nnone\n32 24\n";
  EXPECT_EQ(detect_source_format(root_), SourceFormat::TumMonoVo);
  const std::unique_ptr<Source> source = open_source(root_);
  EXPECT_EQ(source->info().kind, "tum");
  EXPECT_EQ(source->next()->exposure_ms, 3.0);
  // The images folder on its own is a plain image folder.
  EXPECT_EQ(open_source(root_ / "images")->info().kind, "folder");
}

TEST_F(OpenSource, PlainImageFolder) {
  write_image(root_ / "a1.png");
  write_image(root_ / "a2.jpg");
  EXPECT_EQ(detect_source_format(root_), SourceFormat::ImageFolder);
  const std::unique_ptr<Source> source = open_source(root_);
  EXPECT_EQ(source->info().kind, "folder");
  EXPECT_EQ(source->info().frame_count, 2u);
  EXPECT_EQ(to_string(SourceFormat::ImageFolder), "image folder");
}

TEST_F(OpenSource, NothingToOpenIsAnInputError) {
  EXPECT_NE(open_error(root_ / "missing").find("does not exist"), std::string::npos);
  EXPECT_NE(open_error(root_).find("not a recognised sequence"), std::string::npos);
  write_image(root_ / "single.png");
  EXPECT_NE(open_error(root_ / "single.png").find("single image, not a sequence"),
            std::string::npos);
  std::ofstream(root_ / "notes.txt") << "hello";
  EXPECT_NE(open_error(root_ / "notes.txt").find("is a file"), std::string::npos);
  // A folder that only holds other things.
  fs::create_directories(root_ / "other" / "deeper");
  std::ofstream(root_ / "other" / "readme.txt") << "hello";
  EXPECT_FALSE(detect_source_format(root_ / "other").has_value());
  EXPECT_NE(open_error(root_ / "other").find("not a recognised sequence"), std::string::npos);
}

TEST_F(OpenSource, MalformedDatasetErrorsComeFromTheReader) {
  write_image(root_ / "images" / "00000.png");
  std::ofstream(root_ / "times.txt") << "00000 one\n";
  try {
    open_source(root_);
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& error) {
    EXPECT_EQ(error.file(), root_ / "times.txt");
    EXPECT_EQ(error.line(), 1);
  }
}

}  // namespace
}  // namespace nirslam
