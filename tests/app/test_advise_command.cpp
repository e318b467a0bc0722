// `nirslam advise` on sweep folders generated at test time: the per-power table, the fit, the
// recommendation with reasons, the Table 1 layout across folders, and bad inputs named by file
// and line.

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include "app/cli_runner.hpp"
#include "core/sweep_fixtures.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

class AdviseCommand : public ::testing::Test {
protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("nirslam_advise_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // append, not "'" + string: GCC 12 at -O3 warns -Wrestrict inside operator+(const char*, string&&)
  // when it inlines it here (a known false positive, GCC PR 105329).
  std::string quoted(const fs::path& p) const { return std::string("'").append(p.string()).append("'"); }
  fs::path dir_;
};

// The recommended power printed for the folder, or -1.
double recommended_w(const std::string& output) {
  std::smatch m;
  static const std::regex line(R"(Recommended: (\d+) W \(sweep)");
  return std::regex_search(output, m, line) ? std::stod(m[1]) : -1.0;
}

TEST_F(AdviseCommand, PrintsTheTableTheFitAndTheRecommendation) {
  write_sweep_folder(dir_ / "room", {0, 20, 40, 50, 70, 100}, 60.0, 2);
  const CommandResult r = run_command(nirslam("advise " + quoted(dir_ / "room") + " --scene indoor"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* text : {"Indoor room · 6 powers, 12 images", "entropy", "saturated", "sharpness", "features",
                           "coverage", "evenness", "fit of ", "RMS residual", "of the plateau", "confidence",
                           "(the paper's Table 1 layout)", "0 W", "20 W", "40 W", "50 W", "70 W", "100 W"})
    EXPECT_NE(r.output.find(text), std::string::npos) << text << "\n" << r.output;
  const double power = recommended_w(r.output);
  EXPECT_GT(power, 20.0) << r.output;
  EXPECT_LT(power, 100.0) << r.output;
}

TEST_F(AdviseCommand, ClippingLimitAndShareChangeTheAnswer) {
  // The wall reaches full scale at 60 W, its reflectors (2 % of the pixels) at 15 W.
  write_sweep_folder(dir_ / "bright", {0, 5, 10, 20, 30, 40, 50, 70, 100}, 60.0, 1, "", true);
  const CommandResult strict = run_command(nirslam("advise " + quoted(dir_ / "bright") + " --max-clipped 0.01"));
  const CommandResult loose = run_command(nirslam("advise " + quoted(dir_ / "bright") + " --max-clipped 0.5"));
  ASSERT_EQ(strict.exit_code, 0) << strict.output;
  ASSERT_EQ(loose.exit_code, 0) << loose.output;
  EXPECT_NE(strict.output.find("clipping limit binds"), std::string::npos) << strict.output;
  EXPECT_LT(recommended_w(strict.output), recommended_w(loose.output)) << strict.output << loose.output;
  const CommandResult lower_share = run_command(nirslam("advise " + quoted(dir_ / "bright") + " --max-clipped 0.5 --share 0.9"));
  EXPECT_LT(recommended_w(lower_share.output), recommended_w(loose.output)) << lower_share.output;
  EXPECT_NE(strict.output.find("(scene not given)"), std::string::npos) << strict.output;
}

TEST_F(AdviseCommand, SeveralFoldersMakeOneTable1StyleTable) {
  write_sweep_folder(dir_ / "near", {0, 20, 40, 50, 70, 100}, 40.0, 1, "tunnel");
  write_sweep_folder(dir_ / "far", {0, 20, 40, 50, 70, 100}, 140.0, 1, "outdoor");
  const CommandResult r = run_command(nirslam("advise " + quoted(dir_ / "near") + " " + quoted(dir_ / "far") + " --markdown"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("| Scene | 0 W | 20 W | 40 W | 50 W | 70 W | 100 W | Recommended |"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("| Pipe tunnel |"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("| Outdoor at night |"), std::string::npos) << r.output;
  // The far scene needs more power than the near one.
  std::smatch near_m, far_m;
  ASSERT_TRUE(std::regex_search(r.output, near_m, std::regex(R"(\| Pipe tunnel \|.*\| (\d+) W \()")));
  ASSERT_TRUE(std::regex_search(r.output, far_m, std::regex(R"(\| Outdoor at night \|.*\| (\d+) W \()")));
  EXPECT_GT(std::stod(far_m[1]), std::stod(near_m[1])) << r.output;
}

TEST_F(AdviseCommand, ReadsTheSimulatorsSweepTableAndScene) {
  // The columns `nirslam simulate --sweep` writes, and its groundtruth.json naming the scene.
  write_sweep_folder(dir_ / "sim", {0, 20, 40, 50, 70, 100}, 60.0, 1);
  {
    std::ifstream in(dir_ / "sim/sweep.csv");
    std::string header, line, rows;
    std::getline(in, header);
    int i = 0;
    while (std::getline(in, line)) {
      const auto first = line.find(',');
      const auto power = line.substr(line.rfind(',') + 1);
      rows += line.substr(0, first) + ",0," + std::to_string(i++) + ",0.0," + power + ",10.0,1.0,0.4\n";
    }
    std::ofstream(dir_ / "sim/sweep.csv") << "file,viewpoint,frame_index,timestamp_s,power_w,exposure_ms,gain,mean_grey\n"
                                          << rows;
  }
  std::ofstream(dir_ / "sim/groundtruth.json") << R"({"mode": "power_sweep", "scene": {"kind": "parking"}})";
  const CommandResult r = run_command(nirslam("advise " + quoted(dir_ / "sim")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Underground parking · 6 powers, 6 images"), std::string::npos) << r.output;
}

TEST_F(AdviseCommand, TooFewPowersFallBackToThePrior) {
  write_sweep_folder(dir_ / "short", {0, 50}, 60.0, 1);
  const CommandResult r = run_command(nirslam("advise " + quoted(dir_ / "short") + " --scene outdoor"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Recommended: 125 W (prior range 100-150 W, low confidence)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("sweep: 2 of the 4 powers needed"), std::string::npos) << r.output;
}

TEST_F(AdviseCommand, BadInputsAreNamedWithFileAndLine) {
  fs::create_directories(dir_ / "bad/images");
  const CommandResult missing = run_command(nirslam("advise " + quoted(dir_ / "bad")));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find((dir_ / "bad/sweep.csv").string() + ": cannot open"), std::string::npos) << missing.output;

  std::ofstream(dir_ / "bad/sweep.csv") << "file,power_w\nimages/x.png,abc\n";
  const CommandResult power = run_command(nirslam("advise " + quoted(dir_ / "bad")));
  EXPECT_EQ(power.exit_code, 1);
  EXPECT_NE(power.output.find((dir_ / "bad/sweep.csv").string() + ":2: field 'power_w'"), std::string::npos)
      << power.output;

  write_sweep_folder(dir_ / "good", {0, 20, 40, 70}, 60.0, 1);
  const CommandResult scene = run_command(nirslam("advise " + quoted(dir_ / "good") + " --scene moon"));
  EXPECT_EQ(scene.exit_code, 1);
  EXPECT_NE(scene.output.find("--scene: unknown scene 'moon' (room, outdoor, parking, tunnel)"), std::string::npos)
      << scene.output;
  const CommandResult share = run_command(nirslam("advise " + quoted(dir_ / "good") + " --share 1.5"));
  EXPECT_NE(share.exit_code, 0);
  EXPECT_NE(share.output.find("--share"), std::string::npos) << share.output;
  const CommandResult nothing = run_command(nirslam("advise"));
  EXPECT_NE(nothing.exit_code, 0);
}

}  // namespace
}  // namespace nirslam::testing
