// `nirslam calibrate`: DSO/TUM monoVO output and errors against a simulated sequence's ground truth.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "cli_runner.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {
namespace {

using testing::fresh_dir;
using testing::lines_of;
using testing::run_command;

TEST(CalibrateCommand, WritesDsoFilesAndErrorsForASimulatedSequence) {
  const auto dir = fresh_dir("calibrate");
  const std::string exe = NIRSLAM_EXECUTABLE;
  const auto sim = run_command(exe + " simulate --scene room --frames 40 --out " + (dir / "seq").string());
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  // The sequence's vignette.png is the lens alone: the halo factor estimated under the lamp
  // splits into it and the beam.
  const auto r = run_command(exe + " calibrate " + (dir / "seq").string() + " --out " + (dir / "out").string() +
                             " --json " + (dir / "c.json").string() + " --lens-vignette " +
                             (dir / "seq" / "vignette.png").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("errors vs ground truth"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("ambiguity resolution: known exposures"), std::string::npos) << r.output;
  EXPECT_EQ(read_pcalib(dir / "out" / "pcalib.txt").size(), 256u);
  EXPECT_FALSE(read_vignette_png(dir / "out" / "vignette.png").empty());
  EXPECT_EQ(lines_of(dir / "out" / "times.txt").size(), 40u);
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "calibration.json"));
  EXPECT_TRUE(std::filesystem::exists(dir / "c.json"));
  // Where the curves are measured and where they are continuations.
  EXPECT_NE(r.output.find("measured over grey"), std::string::npos) << r.output;
  std::ifstream calibration_file(dir / "out" / "calibration.json");
  const auto calibration = nlohmann::json::parse(calibration_file);
  const auto& observed = calibration.at("observed");
  const double grey_low = observed.at("grey_range").at(0), grey_high = observed.at("grey_range").at(1);
  EXPECT_GE(grey_low, 0.0);
  EXPECT_GT(grey_high, grey_low + 20.0);
  // The simulator reports exposures: the estimates are put on that scale and the output says by what.
  EXPECT_NE(r.output.find("exposures on the reported scale"), std::string::npos) << r.output;
  EXPECT_GT(calibration.at("exposure_scale").at("frames").get<int>(), 0);
  EXPECT_LE(grey_high, 255.0);
  const double radius = observed.at("vignette_max_radius");
  EXPECT_GT(radius, 0.3);
  EXPECT_LE(radius, 1.0);
  EXPECT_NE(r.output.find("lamp beam"), std::string::npos) << r.output;
  EXPECT_FALSE(read_vignette_png(dir / "out" / "beam.png").empty());
  const auto beam = lines_of(dir / "out" / "beam.json");
  std::string text;
  for (const auto& line : beam) text += line;
  EXPECT_NE(text.find("\"beam_exponent\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"determined\""), std::string::npos) << text;
}

TEST(CalibrateCommand, TheConfigsCalibrationSectionMakesItRepeatable) {
  // calibration.background_thread: false (bench-repeatable.yaml) runs the back end inside each
  // frame: two calibrations of one sequence write the same files to the bit. (With the back end
  // on its own thread, which keyframes each optimisation sees depends on the machine's load.)
  const auto dir = fresh_dir("calibrate_repeatable");
  const std::string exe = NIRSLAM_EXECUTABLE;
  const auto sim = run_command(exe + " simulate --scene room --power 0 --ambient 2 --frames 60 --width 320 --height 240 --out " +
                               (dir / "seq").string());
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  const std::string config = std::string(NIRSLAM_SOURCE_DIR) + "/config/bench-repeatable.yaml";
  for (const char* out : {"a", "b"}) {
    const auto r = run_command(exe + " --config " + config + " calibrate " + (dir / "seq").string() + " --out " + (dir / out).string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  EXPECT_EQ(lines_of(dir / "a" / "pcalib.txt"), lines_of(dir / "b" / "pcalib.txt"));
  EXPECT_EQ(lines_of(dir / "a" / "times.txt"), lines_of(dir / "b" / "times.txt"));
  const cv::Mat a = read_vignette_png(dir / "a" / "vignette.png"), b = read_vignette_png(dir / "b" / "vignette.png");
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
}

TEST(CalibrateCommand, TooShortForAnEstimateSaysNothingWasMeasured) {
  // Six frames give the back end no keyframes to fit: the files hold the initial model, and the
  // output says that none of it is measured rather than a range of zeros.
  const auto dir = fresh_dir("calibrate_short");
  const std::string exe = NIRSLAM_EXECUTABLE;
  const auto sim = run_command(exe + " simulate --scene room --frames 6 --width 160 --height 120 --out " + (dir / "seq").string());
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  const auto r = run_command(exe + " calibrate " + (dir / "seq").string() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("no back-end estimate"), std::string::npos) << r.output;
  std::ifstream calibration_file(dir / "out" / "calibration.json");
  const auto calibration = nlohmann::json::parse(calibration_file);
  EXPECT_TRUE(calibration.at("observed").at("grey_range").is_null());
  EXPECT_TRUE(calibration.at("observed").at("vignette_max_radius").is_null());
  EXPECT_TRUE(calibration.at("observed").at("advice").is_null()) << "nothing fitted, nothing to advise";
  EXPECT_EQ(r.output.find("advice:"), std::string::npos) << r.output;
}

// A log response seen only up to grey ~144 (the simulator's auto exposure aims at a mean of
// 0.35): above that the curve is the model's continuation and the response is ~15 grey levels
// off over all levels, so the output says how much brighter the images would have to be. Taken
// that much brighter (the auto exposure's target moved so that its exposures grow by the factor),
// the samples reach higher and the response over all levels is several times closer.
TEST(CalibrateCommand, ImagesThatStopShortOfTheTopGetAdviceAndFollowingItMeasuresTheResponse) {
  const auto dir = fresh_dir("calibrate_range_advice");
  const std::string exe = NIRSLAM_EXECUTABLE;
  const std::string scene = " simulate --scene room --power 0 --ambient 0.4 --texture distance-independent --frames 80 "
                            "--width 320 --height 240 --response log";
  const auto calibrate = [&](const std::string& name, double target_grey) {
    const auto sim = run_command(exe + scene + " --target-grey " + std::to_string(target_grey) + " --out " +
                                 (dir / name).string());
    EXPECT_EQ(sim.exit_code, 0) << sim.output;
    const auto r = run_command(exe + " calibrate " + (dir / name).string() + " --out " + (dir / (name + "_out")).string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    std::ifstream file(dir / (name + "_out") / "calibration.json");
    return std::make_pair(r.output, nlohmann::json::parse(file));
  };
  const auto [dark_output, dark] = calibrate("dark", 0.35);
  EXPECT_NE(dark_output.find("advice: the images reach grey"), std::string::npos) << dark_output;
  const double dark_top = dark.at("observed").at("grey_range").at(1);
  const double dark_error = dark.at("errors").at("response_mean_grey");
  EXPECT_LT(dark_top, 170.0);
  EXPECT_GT(dark_error, 8.0) << "the continuation above grey " << dark_top;
  const double factor = dark.at("observed").at("exposure_factor_to_reach_top");
  EXPECT_GT(factor, 1.8);
  EXPECT_LT(factor, 4.0);
  EXPECT_TRUE(dark.at("observed").at("advice").is_string());

  // The auto exposure's target grey whose exposure is `factor` times the first's, through the true curve.
  const ResponseModel truth = ResponseModel::from_preset(ResponsePreset::Log);
  const double bright_target = truth(factor * truth.inverse(0.35));
  const auto [bright_output, bright] = calibrate("bright", bright_target);
  const double bright_top = bright.at("observed").at("grey_range").at(1);
  const double bright_error = bright.at("errors").at("response_mean_grey");
  EXPECT_GT(bright_top, dark_top + 40.0);
  EXPECT_LT(bright_error, 0.4 * dark_error) << bright_output;
}

TEST(CalibrateCommand, LensVignetteOfAnotherSizeIsNamed) {
  const auto dir = fresh_dir("calibrate_lens");
  const std::string exe = NIRSLAM_EXECUTABLE;
  const auto sim = run_command(exe + " simulate --scene room --frames 12 --width 320 --height 240 --out " + (dir / "seq").string());
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  write_vignette_png(dir / "lens.png", VignetteModel{}.render(640, 480));
  const auto r = run_command(exe + " calibrate " + (dir / "seq").string() + " --out " + (dir / "out").string() +
                             " --lens-vignette " + (dir / "lens.png").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("lens.png"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("640x480"), std::string::npos) << r.output;
}

TEST(CalibrateCommand, MissingFolderIsNamed) {
  const auto r = run_command(std::string(NIRSLAM_EXECUTABLE) + " calibrate /nonexistent/seq --out /tmp/x");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("/nonexistent/seq"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nirslam
