#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "app/cli_runner.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam::testing {
namespace {

const std::filesystem::path kCanonStack = std::filesystem::path(NIRSLAM_SHARED_DATA_DIR) / "exposure_stack_canon_s45";

TEST(CalibrateSweepCommand, CanonStackWithTimesWritesMonotonicPcalibAndJson) {
  if (!std::filesystem::exists(kCanonStack / "shutter.txt")) GTEST_SKIP() << "no " << kCanonStack;
  const auto out = fresh_dir("calibrate_sweep_canon");
  const CommandResult r = run_command(nirslam("calibrate-sweep '" + kCanonStack.string() + "' --times '" +
                                              (kCanonStack / "shutter.txt").string() + "' --green --max-valid 245 --out '" +
                                              out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("known exposure times"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("monotonic yes"), std::string::npos) << r.output;
  const std::vector<double> G = read_pcalib(out / "pcalib.txt");  // throws unless 256 increasing values
  ASSERT_EQ(G.size(), 256u);
  EXPECT_NEAR(G.front(), 0.0, 1e-9);
  EXPECT_NEAR(G.back(), 255.0, 1e-6);
  std::ifstream in(out / "sweep_calibration.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  EXPECT_TRUE(summary.at("monotonic").get<bool>());
  EXPECT_TRUE(summary.at("exposure_times_given").get<bool>());
  EXPECT_NE(summary.at("ambiguity_resolution").get<std::string>().find("known exposure times"), std::string::npos);
  EXPECT_LT(summary.at("residual_rms_grey").get<double>(), 2.5);
  ASSERT_EQ(summary.at("images").size(), 13u);
  EXPECT_FALSE(summary.at("images")[12].at("used").get<bool>());  // img13, 1/1000 s: nearly black
  EXPECT_NEAR(summary.at("images")[1].at("ratio").get<double>(), 10.0 / 13.0, 1e-9);
}

TEST(CalibrateSweepCommand, BlackImagesFailWithReasonAndMissingTimeNamesFile) {
  const auto dir = fresh_dir("calibrate_sweep_black");
  const auto images = dir / "images";
  std::filesystem::create_directories(images);
  for (const char* name : {"a.png", "b.png", "c.png"})
    cv::imwrite((images / name).string(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(0)));
  {
    std::ofstream times(dir / "times.txt");
    times << "a: 1\nb: 1/2\nc: 1/4\n";
  }
  const CommandResult black =
      run_command(nirslam("calibrate-sweep '" + images.string() + "' --times '" + (dir / "times.txt").string() + "'"));
  EXPECT_EQ(black.exit_code, 1) << black.output;
  EXPECT_NE(black.output.find("black or saturated"), std::string::npos) << black.output;
  EXPECT_EQ(black.output.find("nan"), std::string::npos) << black.output;
  {
    std::ofstream times(dir / "short.txt");
    times << "a: 1\nb: 1/2\n";
  }
  const CommandResult missing =
      run_command(nirslam("calibrate-sweep '" + images.string() + "' --times '" + (dir / "short.txt").string() + "'"));
  EXPECT_EQ(missing.exit_code, 1) << missing.output;
  EXPECT_NE(missing.output.find("short.txt"), std::string::npos) << missing.output;
  EXPECT_NE(missing.output.find("no exposure time for image 'c.png'"), std::string::npos) << missing.output;
}

}  // namespace
}  // namespace nirslam::testing
