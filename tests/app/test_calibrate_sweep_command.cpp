#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "app/cli_runner.hpp"
#include "nirslam/image/image_codec.hpp"
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
    nirslam::write_image(images / name, cv::Mat(48, 64, CV_8UC1, cv::Scalar(0)));
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

// Issue 6: the response from an illuminator power sweep. The simulator renders one viewpoint of
// the room at 12 lamp powers, fixed exposure, no ambient light; calibrate-sweep --power-sweep
// takes power x exposure as the known exposures, and its pcalib.txt is compared with the true
// (log) inverse response over the grey levels the sweep covers.
TEST(CalibrateSweepCommand, PowerSweepRecoversTheSimulatedResponse) {
  const auto dir = fresh_dir("calibrate_power_sweep");
  const CommandResult sim = run_command(nirslam(
      "simulate --out '" + (dir / "sweep").string() +
      "' --scene room --width 160 --height 120 --response log --exposure 4 --ambient 0 "
      "--texture distance-independent --sweep 5,10,15,20,30,40,50,65,80,100,125,150"));
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  const CommandResult r = run_command(nirslam("calibrate-sweep '" + (dir / "sweep").string() + "' --power-sweep --out '" +
                                              (dir / "out").string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("illuminator power sweep"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("monotonic yes"), std::string::npos) << r.output;
  const std::vector<double> G = read_pcalib(dir / "out" / "pcalib.txt");
  const std::vector<double> truth = ResponseModel::from_preset(ResponsePreset::Log).inverse_table(256);
  ASSERT_EQ(G.size(), 256u);
  double mean = 0.0, worst = 0.0;
  for (std::size_t i = 0; i < 256; ++i) {
    const double d = std::abs(G[i] - truth[i]);
    mean += d / 256.0;
    worst = std::max(worst, d);
  }
  std::printf("power sweep response error: mean %.2f, max %.2f grey levels\n", mean, worst);
  EXPECT_LT(mean, 2.0);
  EXPECT_LT(worst, 10.0);
  std::ifstream in(dir / "out" / "sweep_calibration.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  EXPECT_TRUE(summary.at("power_sweep").get<bool>());
  EXPECT_EQ(summary.at("images").size(), 12u);
}

TEST(CalibrateSweepCommand, PowerSweepWithoutSweepCsvNamesTheFile) {
  const auto dir = fresh_dir("calibrate_power_sweep_missing");
  const CommandResult r = run_command(nirslam("calibrate-sweep '" + dir.string() + "' --power-sweep"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("sweep.csv"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nirslam::testing
