#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "app/cli_runner.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/image/frame.hpp"
#include "nirslam/photometric/response_model.hpp"
#include "nirslam/session/session_recorder.hpp"

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
  EXPECT_TRUE(summary.at("reported_exposure_check").is_null()) << summary.at("reported_exposure_check");
  EXPECT_EQ(r.output.find("warning: the brightness of"), std::string::npos) << r.output;
}

// A shutter time that is not the image's own (img05's 1 s given as 2 s, a whole stop: what a
// camera reporting its previous setting gives) is named with the factor its brightness says.
TEST(CalibrateSweepCommand, AnExposureTheBrightnessDisagreesWithIsNamed) {
  if (!std::filesystem::exists(kCanonStack / "shutter.txt")) GTEST_SKIP() << "no " << kCanonStack;
  const auto out = fresh_dir("calibrate_sweep_wrong_time");
  std::ifstream original(kCanonStack / "shutter.txt");
  std::ofstream doctored(out / "shutter.txt");
  std::string line;
  int replaced = 0;
  while (std::getline(original, line)) {
    if (line.rfind("img05", 0) == 0) {
      line = "img05.jpg: 2";
      ++replaced;
    }
    doctored << line << "\n";
  }
  doctored.close();
  ASSERT_EQ(replaced, 1);
  const CommandResult r = run_command(nirslam("calibrate-sweep '" + kCanonStack.string() + "' --times '" +
                                              (out / "shutter.txt").string() + "' --green --max-valid 245 --out '" +
                                              out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::size_t warning = r.output.find("warning: the brightness of ");
  ASSERT_NE(warning, std::string::npos) << r.output;
  const std::size_t named = warning + std::string("warning: the brightness of ").size();
  const std::string images = r.output.substr(named, r.output.find(" disagrees", named) - named);
  EXPECT_EQ(images.rfind("img05.jpg (0.", 0), 0u) << images;
  EXPECT_EQ(images.find(", "), std::string::npos) << "img05 alone: " << images;
  std::ifstream in(out / "sweep_calibration.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  const double factor = summary.at("images")[4].at("brightness_exposure_factor").get<double>();
  EXPECT_GT(factor, 0.4);
  EXPECT_LT(factor, 0.7);
  EXPECT_NE(summary.at("reported_exposure_check").get<std::string>().find("image 4 ("), std::string::npos);
  std::printf("img05 given 2 s for its 1 s: brightness %.3fx\n", factor);
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

// One viewpoint at each of `powers_w` (comma-separated), a fixed 4 ms, the log response, texture
// independent of the distance; by default the room without ambient light.
void simulate_sweep(const std::filesystem::path& out, const std::string& powers_w,
                    const std::string& scene = "room --ambient 0") {
  const CommandResult sim = run_command(nirslam("simulate --out '" + out.string() + "' --scene " + scene +
                                                " --width 160 --height 120 --response log --exposure 4 "
                                                "--texture distance-independent --sweep " + powers_w));
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
}

// Issue 6: the response from an illuminator power sweep. The simulator renders one viewpoint of
// the room at 12 lamp powers, fixed exposure, no ambient light; calibrate-sweep --power-sweep
// takes power x exposure as the known exposures, and its pcalib.txt is compared with the true
// (log) inverse response over the grey levels the sweep covers.
TEST(CalibrateSweepCommand, PowerSweepRecoversTheSimulatedResponse) {
  const auto dir = fresh_dir("calibrate_power_sweep");
  simulate_sweep(dir / "sweep", "5,10,15,20,30,40,50,65,80,100,125,150");
  if (HasFatalFailure()) return;
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

// The same sweep as a rig records it: a session (the worker's recorder, as the Record tab runs it)
// in which the camera stands still while the lamp is stepped through its powers, five frames at
// each, starting with the lamp off. calibrate-sweep reads the journal's exposures and powers.
TEST(CalibrateSweepCommand, ARecordedSessionServesAsAPowerSweep) {
  const auto dir = fresh_dir("calibrate_power_sweep_session");
  simulate_sweep(dir / "sweep", "0,5,10,20,40,65,100,150");
  if (HasFatalFailure()) return;
  std::ifstream table(dir / "sweep" / "sweep.csv");
  std::string line;
  std::getline(table, line);  // header: file,viewpoint,frame_index,timestamp_s,power_w,exposure_ms,gain,mean_grey
  std::vector<std::pair<std::string, double>> images;
  while (std::getline(table, line)) {
    std::vector<std::string> cells;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    ASSERT_GE(cells.size(), 6u) << line;
    images.emplace_back(cells[0], std::stod(cells[4]));
  }
  ASSERT_EQ(images.size(), 8u);
  const auto record = [&](const std::filesystem::path& session, bool with_power, int bit_depth = 8) {
    SessionRecorder recorder(session, {"simulated", "power sweep", 30.0, nullptr});
    std::int64_t index = 0;
    for (const auto& [file, power] : images)
      for (int repeat = 0; repeat < 5; ++repeat, ++index) {
        Frame frame;
        frame.image = read_image(dir / "sweep" / file);
        if (bit_depth == 16) frame.image.convertTo(frame.image, CV_16U, 257.0);  // a Y16 camera's frames
        frame.bit_depth = bit_depth;
        frame.index = index;
        frame.timestamp_s = index / 30.0;
        frame.exposure_ms = 4.0;
        frame.gain = 1.0;
        if (with_power) frame.illuminator_power_w = power;
        ASSERT_TRUE(recorder.record(frame));
      }
    recorder.stop("end of sweep");
  };
  record(dir / "session", true);
  const CommandResult r = run_command(nirslam("calibrate-sweep '" + (dir / "session").string() + "' --power-sweep --out '" +
                                              (dir / "out").string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("monotonic yes"), std::string::npos) << r.output;
  const std::vector<double> G = read_pcalib(dir / "out" / "pcalib.txt");
  const std::vector<double> truth = ResponseModel::from_preset(ResponsePreset::Log).inverse_table(256);
  ASSERT_EQ(G.size(), 256u);
  double mean = 0.0;
  for (std::size_t i = 0; i < 256; ++i) mean += std::abs(G[i] - truth[i]) / 256.0;
  std::printf("power sweep from a recorded session: response error mean %.2f grey levels\n", mean);
  EXPECT_LT(mean, 2.0);
  std::ifstream in(dir / "out" / "sweep_calibration.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  // Eight powers (0 W too: it shows the ambient light), the first two frames of each skipped,
  // three left of five.
  EXPECT_EQ(summary.at("images").size(), 24u);
  // Its 0 W frames (the first two after the start skipped) show no other light: the lamp the only one.
  EXPECT_NE(r.output.find("ambient light (000002.png at 0 W): 0.0 % of the irradiance at 5 W"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("warning: the lamp is not the only light"), std::string::npos) << r.output;
  // A 16-bit session (a Y16 camera) is read on the same 0..255 scale, so the same response.
  record(dir / "session16", true, 16);
  const CommandResult wide = run_command(nirslam("calibrate-sweep '" + (dir / "session16").string() +
                                                 "' --power-sweep --out '" + (dir / "out16").string() + "'"));
  ASSERT_EQ(wide.exit_code, 0) << wide.output;
  EXPECT_NE(wide.output.find("24 16-bit images read on the 0..255 scale"), std::string::npos) << wide.output;
  const std::vector<double> G16 = read_pcalib(dir / "out16" / "pcalib.txt");
  ASSERT_EQ(G16.size(), 256u);
  for (std::size_t i = 0; i < 256; ++i) EXPECT_NEAR(G16[i], G[i], 1e-6) << i;
  // Without the lamp's power in the journal it is no power sweep, and the error says where.
  record(dir / "session_without_power", false);
  const CommandResult bad = run_command(nirslam("calibrate-sweep '" + (dir / "session_without_power").string() +
                                                "' --power-sweep"));
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("journal.csv:2"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("illuminator_power_w"), std::string::npos) << bad.output;
}

// Light the lamp does not give (here the room lit 100 times as brightly as at night: 40-60 % of
// the irradiance at 5 W) bends a power sweep's response unless the fit carries a per-point ambient
// term. Measured: with the term 0.07 / 0.28 grey levels mean / max, with --no-ambient 5.07 / 10.7
// and the 0 W image's warning.
TEST(CalibrateSweepCommand, PowerSweepModelsAmbientLight) {
  const auto dir = fresh_dir("calibrate_power_sweep_ambient");
  simulate_sweep(dir / "sweep", "0,5,10,20,40,65,100,150", "room --ambient 0.2");
  if (HasFatalFailure()) return;
  const std::vector<double> truth = ResponseModel::from_preset(ResponsePreset::Log).inverse_table(256);
  const auto mean_error = [&](const std::filesystem::path& out) {
    const std::vector<double> G = read_pcalib(out / "pcalib.txt");
    double mean = 0.0;
    for (std::size_t i = 0; i < 256 && i < G.size(); ++i) mean += std::abs(G[i] - truth[i]) / 256.0;
    return G.size() == 256 ? mean : 1e9;
  };
  const CommandResult r = run_command(nirslam("calibrate-sweep '" + (dir / "sweep").string() + "' --power-sweep --out '" +
                                              (dir / "out").string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("plus per point an ambient radiance"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("ambient term: median"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("warning: the lamp is not the only light"), std::string::npos) << r.output;
  std::ifstream in(dir / "out" / "sweep_calibration.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  EXPECT_TRUE(summary.at("ambient_modelled").get<bool>());
  EXPECT_GT(summary.at("ambient_share_at_lowest_power").get<double>(), 0.2);
  EXPECT_GT(summary.at("ambient_share_fitted").get<double>(), 0.2);
  EXPECT_EQ(summary.at("images").size(), 8u) << "the 0 W image observes the ambient light";
  const double with_term = mean_error(dir / "out");

  const CommandResult off = run_command(nirslam("calibrate-sweep '" + (dir / "sweep").string() +
                                                "' --power-sweep --no-ambient --out '" + (dir / "out_off").string() + "'"));
  ASSERT_EQ(off.exit_code, 0) << off.output;
  EXPECT_NE(off.output.find("warning: the lamp is not the only light"), std::string::npos) << off.output;
  EXPECT_NE(off.output.find("0 W: ambient light only"), std::string::npos) << off.output;
  const double without_term = mean_error(dir / "out_off");
  std::printf("power sweep under ambient light: response error mean %.2f grey levels with the ambient term, %.2f "
              "without\n",
              with_term, without_term);
  EXPECT_LT(with_term, 0.5);
  EXPECT_GT(without_term, 2.0);
}

TEST(CalibrateSweepCommand, PowerSweepWithoutSweepCsvNamesTheFile) {
  const auto dir = fresh_dir("calibrate_power_sweep_missing");
  const CommandResult r = run_command(nirslam("calibrate-sweep '" + dir.string() + "' --power-sweep"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("sweep.csv"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nirslam::testing
