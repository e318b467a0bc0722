// Reading a sweep folder (sweep.csv + images) and measuring it, with every malformed input named
// by file and line.

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include "core/sweep_fixtures.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/illumination/advisor.hpp"
#include "nirslam/illumination/sweep_folder.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

class SweepFolderTest : public ::testing::Test {
protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("nirslam_sweep_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string error_of(const std::string& csv) {
    fs::create_directories(dir_ / "images");
    nirslam::write_image(dir_ / "images/a.png", cv::Mat(8, 8, CV_8UC1, cv::Scalar(9)));
    std::ofstream(dir_ / "sweep.csv") << csv;
    try {
      read_sweep_folder(dir_);
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  }

  fs::path dir_;
};

TEST_F(SweepFolderTest, ReadsTheTableAndMeasuresEveryImageAtItsPower) {
  const std::vector<double> powers{0, 20, 40, 50, 70, 100};
  testing::write_sweep_folder(dir_, powers, 60.0, 2);
  const SweepFolder folder = read_sweep_folder(dir_);
  ASSERT_EQ(folder.images.size(), 12u);
  EXPECT_EQ(folder.images[0].line, 2);
  EXPECT_DOUBLE_EQ(folder.images[11].power_w, 100.0);
  EXPECT_FALSE(folder.ground_truth_scene);

  QualityMeter meter;
  const auto records = measure_sweep(folder, meter, "room");
  ASSERT_EQ(records.size(), 1u);
  const SweepRecord& sweep = records.at("room");
  ASSERT_EQ(sweep.points().size(), powers.size());
  for (const SweepPoint& p : sweep.points()) EXPECT_EQ(p.frames, 2);
  // Only dark noise at 0 W, brighter with power, clipped at the top.
  EXPECT_LT(sweep.points()[0].entropy_bits.mean, sweep.points()[2].entropy_bits.mean - 1.0);
  EXPECT_LT(sweep.points()[0].mean.mean, 0.1);
  EXPECT_GT(sweep.points()[2].entropy_bits.mean, sweep.points()[1].entropy_bits.mean);
  EXPECT_GT(sweep.points()[2].mean.mean, sweep.points()[1].mean.mean);
  EXPECT_GT(sweep.points().back().saturated_fraction.mean, 0.05);
  EXPECT_GT(sweep.points()[3].feature_count.mean, 10.0);
  // And the advisor makes something of it: within the sweep, not clipped beyond the limit.
  const Recommendation r = recommend_from_sweep(sweep.points(), {}, {});
  ASSERT_EQ(r.source, RecommendationSource::Sweep);
  EXPECT_GT(r.power_w, 20.0);
  EXPECT_LT(r.power_w, 100.0);
  ASSERT_TRUE(r.expected_saturated_fraction);
  EXPECT_LE(*r.expected_saturated_fraction, 0.01 + 1e-12);
}

TEST_F(SweepFolderTest, SceneComesFromTheColumnOrTheSimulatorsGroundTruth) {
  testing::write_sweep_folder(dir_, {0, 50}, 60.0, 1, "tunnel");
  std::ofstream(dir_ / "groundtruth.json") << R"({"mode": "power_sweep", "scene": {"kind": "parking"}})";
  const SweepFolder folder = read_sweep_folder(dir_);
  EXPECT_EQ(folder.images[0].scene, "tunnel");
  EXPECT_EQ(folder.ground_truth_scene, "parking");
  QualityMeter meter;
  EXPECT_EQ(measure_sweep(folder, meter, "room").count("tunnel"), 1u);
}

TEST_F(SweepFolderTest, ErrorsNameTheTableAndTheLine) {
  const std::string table = (dir_ / "sweep.csv").string();
  EXPECT_EQ(error_of("file,watts\nimages/a.png,10\n"),
            table + ":1: the header must name the columns 'file' and 'power_w' (and optionally 'scene'), got "
                    "'file,watts'");
  EXPECT_EQ(error_of("file,power_w\nimages/a.png,10\nimages/a.png,ten\n"),
            table + ":3: field 'power_w': expected watts >= 0, got 'ten'");
  EXPECT_EQ(error_of("file,power_w\nimages/a.png,-5\n"), table + ":2: field 'power_w': expected watts >= 0, got '-5'");
  EXPECT_EQ(error_of("# a comment\nfile,power_w\n\nimages/a.png,10,3\n"),
            table + ":4: expected 2 fields as in the header, got 3");
  EXPECT_EQ(error_of("file,power_w\n,10\n"), table + ":2: field 'file' is empty");
  EXPECT_NE(error_of("file,power_w\nimages/missing.png,10\n").find(table + ":2: image 'images/missing.png' not found"),
            std::string::npos);
  EXPECT_EQ(error_of(""), table + ": empty: expected a header 'file,power_w' and one line per image");
  EXPECT_EQ(error_of("file,power_w\n"), table + ": lists no images");
  fs::remove(dir_ / "sweep.csv");
  try {
    read_sweep_folder(dir_);
    ADD_FAILURE() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(table + ": cannot open"), std::string::npos) << e.what();
  }
}

TEST_F(SweepFolderTest, UndecodableImageIsNamedWithItsLine) {
  fs::create_directories(dir_ / "images");
  std::ofstream(dir_ / "images/bad.png") << "not a png";
  std::ofstream(dir_ / "sweep.csv") << "file,power_w\nimages/bad.png,20\n";
  const SweepFolder folder = read_sweep_folder(dir_);
  QualityMeter meter;
  try {
    measure_sweep(folder, meter, "room");
    ADD_FAILURE() << "expected an error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find((dir_ / "sweep.csv").string() + ":2:"), std::string::npos) << what;
    EXPECT_NE(what.find("bad.png"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace nirslam
