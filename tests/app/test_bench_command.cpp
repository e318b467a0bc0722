// `nirslam bench` on a tiny suite: it renders the simulated sequence once, runs it in every
// odometry mode, evaluates against the ground truth and writes the Table 2 layout.

#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "app/cli_runner.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

TEST(BenchCommand, TinySuiteWritesTheTableWithAnAtePerMode) {
  const fs::path out = fresh_dir("bench_tiny");
  const CommandResult r =
      run_command(nirslam("bench --scenes room --powers 50 --frames 40 --size 320x240 --out '" + out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("[1/3] Room_50"), std::string::npos) << "progress per run\n" << r.output;
  const auto md = lines_of(out / "bench.md");
  ASSERT_GE(md.size(), 3u);
  // The paper's Table 2 columns: plain, + calibration, + the lamp's correction.
  EXPECT_EQ(md[0].rfind("| Sequence | ATE odometry [m] | ATE calibrated [m] | ATE illuminated [m] | "
                        "Improvement illuminated vs calibrated [%]",
                        0),
            0u)
      << md[0];
  EXPECT_EQ(md[2].rfind("| Room_50 | 0.", 0), 0u) << "an ATE in metres for the first mode\n" << md[2];
  const auto csv = lines_of(out / "bench.csv");
  ASSERT_EQ(csv.size(), 2u);
  EXPECT_EQ(csv[1].rfind("Room_50,0.", 0), 0u) << csv[1];
  // Each mode's keyframe count, from its run's summary: the third column.
  EXPECT_EQ(csv[0].rfind("sequence,ate_m_odometry,segments_odometry,keyframes_odometry,", 0), 0u) << csv[0];
  std::vector<std::string> cells;
  for (std::size_t start = 0, comma = 0; comma != std::string::npos; start = comma + 1) {
    comma = csv[1].find(',', start);
    cells.push_back(csv[1].substr(start, comma == std::string::npos ? std::string::npos : comma - start));
  }
  ASSERT_GT(cells.size(), 3u) << csv[1];
  const int keyframes = std::stoi(cells[3]);
  EXPECT_GE(keyframes, 2) << csv[1];
  EXPECT_LE(keyframes, 40) << csv[1];
  EXPECT_NE(r.output.find(" keyframes"), std::string::npos) << "the progress line says how many\n" << r.output;
  EXPECT_TRUE(fs::exists(out / "runs/Room_50/calibrated/trajectory.txt"));
  EXPECT_TRUE(fs::exists(out / "runs/Room_50/illuminated/trajectory.txt"));

  // A second bench reuses the rendered sequence, and hands its --config to every run; with
  // --dataset-calibration the calibrated runs hold the sequence's own (here: true) calibration.
  const fs::path config = out / "my-pipeline.yaml";
  fs::copy_file(fs::path(NIRSLAM_SOURCE_DIR) / "config/pipeline.yaml", config);
  const CommandResult again = run_command(nirslam("--config '" + config.string() +
                                                  "' bench --scenes room --powers 50 --frames 40 --size 320x240 --modes calibrated "
                                                  "--dataset-calibration --out '" + out.string() + "'"));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(again.output.find("rendering"), std::string::npos) << again.output;
  const auto summary = lines_of(out / "runs/Room_50/calibrated/summary.json");
  bool names_config = false, names_calibration = false;
  for (const std::string& line : summary) {
    names_config |= line.find("my-pipeline.yaml") != std::string::npos;
    names_calibration |= line.find("\"folder\": \"" + (out / "sequences").string()) != std::string::npos;
  }
  EXPECT_TRUE(names_config) << "the run's summary names bench's --config file";
  EXPECT_TRUE(names_calibration) << "the run's summary names the given calibration";
  const auto given_md = lines_of(out / "bench.md");
  ASSERT_FALSE(given_md.empty());
  EXPECT_EQ(given_md[0].rfind("Photometric calibration given (run --photometric-calibration) in mode calibrated: each "
                              "sequence's own pcalib.txt and vignette.png; both held",
                              0),
            0u)
      << given_md[0];

  // One folder for every sequence, held by the lamp mode only (issue 8's lens vignette from an
  // earlier calibration, the beam refined online); the calibrated mode estimates everything
  // online, though the config's estimate_beam would refuse to run without a given lens vignette.
  const fs::path lens_config = fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-lens-vignette-beam-refined.yaml";
  const fs::path rig = out / "sequences" / "Room_50_40f_320x240";
  ASSERT_TRUE(fs::exists(rig / "vignette.png"));
  // `bench` with a config, the rig's folder held by the lamp mode; bench.md's first line says so.
  const auto bench_over_rig = [&](const fs::path& rig_config, const std::string& modes) {
    return run_command(nirslam("--config '" + rig_config.string() + "' bench --scenes room --powers 50 --frames 40 --size "
                               "320x240 --modes " + modes + " --photometric-calibration '" + rig.string() +
                               "' --given-calibration-modes illuminated --out '" + out.string() + "'"));
  };
  const auto expect_header = [&](const std::string& held) {
    const auto header = lines_of(out / "bench.md");
    ASSERT_FALSE(header.empty());
    EXPECT_EQ(header[0].rfind("Photometric calibration given (run --photometric-calibration) in mode illuminated: the " + held, 0),
              0u)
        << header[0];
  };
  const CommandResult lamp = bench_over_rig(lens_config, "calibrated,illuminated");
  ASSERT_EQ(lamp.exit_code, 0) << lamp.output;
  const auto summary_text = [&](const char* mode) {
    std::string text;
    for (const std::string& line : lines_of(out / "runs/Room_50" / mode / "summary.json")) text += line;
    return text;
  };
  EXPECT_NE(summary_text("illuminated").find("\"held\": \"vignette\""), std::string::npos) << summary_text("illuminated");
  EXPECT_NE(summary_text("calibrated").find("\"photometric_calibration\": \"online\""), std::string::npos)
      << summary_text("calibrated");
  expect_header("vignette.png of " + rig.string() + "; the lens vignette (vignette.png) held, "
                "the lamp's beam (exponent 4.82, refined online) in the odometry's lamp factor");
  // The response from a sweep held by the lamp mode, its halo factor the beam over a flat lens.
  const CommandResult swept = bench_over_rig(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-lamp-sweep-response.yaml", "illuminated");
  ASSERT_EQ(swept.exit_code, 0) << swept.output;
  EXPECT_NE(summary_text("illuminated").find("\"held\": \"response\""), std::string::npos) << summary_text("illuminated");
  expect_header("pcalib.txt of " + rig.string() + "; the response (pcalib.txt) held, the halo factor estimated online "
                "(in the illuminated mode as the lamp's beam over a flat lens)");
}

TEST(BenchCommand, AGivenCalibrationsModesAndFolderAreChecked) {
  const fs::path out = fresh_dir("bench_given_bad");
  const CommandResult plain = run_command(nirslam("bench --no-simulated demo --modes odometry,calibrated --photometric-calibration '" +
                                                  out.string() + "' --given-calibration-modes odometry --out '" + out.string() + "'"));
  EXPECT_NE(plain.exit_code, 0);
  EXPECT_NE(plain.output.find("--given-calibration-modes: 'odometry'"), std::string::npos) << plain.output;
  const CommandResult missing = run_command(nirslam("bench --no-simulated demo --photometric-calibration /no/such/calibration --out '" +
                                                    out.string() + "'"));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("/no/such/calibration"), std::string::npos) << missing.output;
  const CommandResult both = run_command(nirslam("bench --no-simulated demo --dataset-calibration --photometric-calibration '" +
                                                 out.string() + "' --out '" + out.string() + "'"));
  EXPECT_NE(both.exit_code, 0);
  EXPECT_NE(both.output.find("give one of the two"), std::string::npos) << both.output;
}

TEST(BenchCommand, QualityIsNotAnOdometryMode) {
  const CommandResult r = run_command(nirslam("bench --modes quality --no-simulated demo --out '" + fresh_dir("bench_bad").string() + "'"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("not an odometry mode"), std::string::npos) << r.output;
}

TEST(BenchCommand, MissingDatasetIsNamed) {
  const CommandResult r = run_command(nirslam("bench --no-simulated /no/such/dataset --out '" + fresh_dir("bench_missing").string() + "'"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("/no/such/dataset"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nirslam::testing
