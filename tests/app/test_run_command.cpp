#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "app/cli_runner.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

TEST(RunCommand, DemoWritesOneCsvRowPerFrameAndASummary) {
  const fs::path out = fresh_dir("demo");
  const CommandResult r = run_command(nirslam("run demo --max-frames 20 --out '" + out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto rows = lines_of(out / "quality.csv");
  ASSERT_EQ(rows.size(), 21u);
  EXPECT_EQ(rows[0].rfind("frame_index,timestamp_s,exposure_ms,illuminator_power_w,entropy_bits", 0), 0u);
  EXPECT_EQ(rows[1].rfind("0,0.000000000,10.000000,50.000000,", 0), 0u) << rows[1];
  // The image metrics of the illumination advisor close each row.
  EXPECT_NE(rows[0].find(",mean,rms_contrast,gradient_energy,feature_count,feature_coverage,feature_evenness"),
            std::string::npos)
      << rows[0];
  EXPECT_EQ(std::count(rows[1].begin(), rows[1].end(), ','), std::count(rows[0].begin(), rows[0].end(), ','));
  std::ifstream summary_file(out / "summary.json");
  const auto summary = nlohmann::json::parse(summary_file);
  EXPECT_EQ(summary["frames_processed"], 20);
  EXPECT_EQ(summary["state"], "finished");
  EXPECT_GT(summary["mean_entropy_bits"].get<double>(), 5.0);  // a textured scene, not a blank image
  EXPECT_NE(r.output.find(out.string()), std::string::npos) << "says where the output went\n" << r.output;
}

TEST(RunCommand, RealEurocSequenceKeepsItsTimestamps) {
  const fs::path out = fresh_dir("euroc");
  const fs::path dataset = fs::path(NIRSLAM_SHARED_DATA_DIR) / "euroc_v1_01_micro";
  const CommandResult r = run_command(nirslam("run '" + dataset.string() + "' --out '" + out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto rows = lines_of(out / "quality.csv");
  ASSERT_EQ(rows.size(), 96u);  // header + 95 frames
  EXPECT_EQ(rows[1].rfind("0,1403715273.262142", 0), 0u) << rows[1];
  EXPECT_EQ(rows[95].rfind("94,1403715277.962142", 0), 0u) << rows[95];
}

TEST(RunCommand, MissingDatasetIsNamed) {
  const CommandResult r = run_command(nirslam("run /no/such/dataset --out '" + fresh_dir("missing").string() + "'"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("/no/such/dataset"), std::string::npos) << r.output;
}

TEST(RunCommand, FullDiskStopsWithAClearMessage) {
  // /dev/full fails every write with ENOSPC, as a full disk does.
  const fs::path out = fresh_dir("full");
  fs::create_directories(out);
  fs::create_symlink("/dev/full", out / "quality.csv");
  const CommandResult r = run_command(nirslam("run demo --max-frames 5 --out '" + out.string() + "'"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("quality.csv"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("No space left on device"), std::string::npos) << r.output;
}

TEST(RunCommand, WriteFailureMidStreamKeepsTheRowsAlreadyWritten) {
  // A 4 KiB file-size limit lets about 40 rows through, then every write fails (EFBIG), as a disk
  // filling up during a run would. SIGXFSZ is ignored so the write returns an error instead.
  const fs::path out = fresh_dir("limit");
  const CommandResult r = run_command("bash -c \"trap '' XFSZ; ulimit -f 4; " +
                                      nirslam("run demo --max-frames 200 --out '" + out.string() + "'") + "\"");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("quality.csv: cannot write"), std::string::npos) << r.output;
  const auto rows = lines_of(out / "quality.csv");
  ASSERT_GT(rows.size(), 10u);
  ASSERT_LT(rows.size(), 200u);
  // Every complete row is intact and in order; at most the row being written is cut.
  for (std::size_t i = 1; i + 1 < rows.size(); ++i)
    EXPECT_EQ(rows[i].rfind(std::to_string(i - 1) + ",", 0), 0u) << rows[i];
}

TEST(RunCommand, ConfigFileSetsTheDemoSequence) {
  const fs::path out = fresh_dir("config");
  fs::create_directories(out);
  std::ofstream(out / "short.yaml") << "demo:\n  frames: 7\n  width: 320\n  height: 240\n";
  const CommandResult r = run_command(nirslam("--config '" + (out / "short.yaml").string() + "' run demo --out '" +
                                              out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(lines_of(out / "quality.csv").size(), 8u);

  std::ofstream(out / "typo.yaml") << "demo:\n  frmaes: 7\n";
  const CommandResult bad = run_command(nirslam("--config '" + (out / "typo.yaml").string() + "' run demo --out '" +
                                                out.string() + "'"));
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.output.find("typo.yaml:2: field 'demo.frmaes': unknown key"), std::string::npos) << bad.output;
}

TEST(Cli, VersionAndHelp) {
  const CommandResult version = run_command(nirslam("--version"));
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_NE(version.output.find("nirslam 0."), std::string::npos) << version.output;
  const CommandResult help = run_command(nirslam("--help"));
  EXPECT_EQ(help.exit_code, 0);
  for (const char* sub : {"gui", "run", "entropy"})
    EXPECT_NE(help.output.find(sub), std::string::npos) << sub << "\n" << help.output;
}

}  // namespace
}  // namespace nirslam::testing

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

// A short simulated room (small frames, lamp off so the exposures are observable) on disk.
fs::path small_room_sequence() {
  static const fs::path folder = [] {
    const fs::path f = fresh_dir("small_room_sequence");
    const CommandResult r = run_command(nirslam("simulate --scene room --power 0 --ambient 2 --frames 40 --width 320 "
                                                "--height 240 --supersampling 1 -o '" + f.string() + "'"));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return f;
  }();
  return folder;
}

TEST(RunCommand, CalibratedModeWritesTrajectoryCalibrationAndSummary) {
  const fs::path out = fresh_dir("calibrated");
  fs::create_directories(out);
  // The odometry waits for the back end's first fitted model (frame 8 here on an idle machine), by
  // default up to 30 frames; a short wait keeps "most of the sequence" true on a busy one.
  std::ofstream(out / "short_wait.yaml") << "pipeline:\n  odometry_waits_for_model_frames: 5\n";
  const CommandResult r = run_command(nirslam("--config '" + (out / "short_wait.yaml").string() + "' run '" +
                                              small_room_sequence().string() + "' --mode calibrated --out '" +
                                              out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* file : {"quality.csv", "trajectory.txt", "keyframes.txt", "points.ply", "summary.json",
                           "calibration/pcalib.txt", "calibration/vignette.png", "calibration/times.txt",
                           "calibration/calibration.json"})
    EXPECT_TRUE(fs::exists(out / file)) << file << "\n" << r.output;
  std::ifstream summary_file(out / "summary.json");
  const auto summary = nlohmann::json::parse(summary_file);
  EXPECT_EQ(summary["mode"], "calibrated");
  EXPECT_EQ(summary["frames_processed"], 40);
  EXPECT_GT(summary["odometry"]["poses"].get<int>(), 20) << "the odometry tracked most of the sequence";
  EXPECT_GT(summary["peak_memory_mib"].get<double>(), 10.0);
  EXPECT_GT(summary["mean_ms"]["odometry"].get<double>(), 0.0);
  // Per-frame rows carry the stages' figures: exposure estimate and tracking status.
  const auto rows = lines_of(out / "quality.csv");
  ASSERT_EQ(rows.size(), 41u);
  EXPECT_NE(rows[0].find(",photometric_ms,odometry_ms,mapping_ms,exposure_estimate,tracking,keyframe,residual_rms"),
            std::string::npos);
  EXPECT_NE(rows[40].find(",tracking,"), std::string::npos) << rows[40];
  // The trajectory is TUM and covers the frames with a pose.
  const auto poses = lines_of(out / "trajectory.txt");
  EXPECT_GE(std::count_if(poses.begin(), poses.end(), [](const std::string& l) { return !l.empty() && l[0] != '#'; }), 20);
}

TEST(RunCommand, GivenPhotometricCalibrationIsHeldAndNamed) {
  // The simulated folder is a TUM monoVO dataset with the true pcalib.txt and vignette.png: run
  // as DSO runs on such a folder.
  const fs::path out = fresh_dir("given_calibration");
  const fs::path sequence = small_room_sequence();
  const CommandResult r = run_command(nirslam("run '" + sequence.string() + "' --mode calibrated --max-frames 20 "
                                              "--photometric-calibration '" + sequence.string() + "' --out '" + out.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("photometric calibration given"), std::string::npos) << r.output;
  std::ifstream summary_file(out / "summary.json");
  const auto summary = nlohmann::json::parse(summary_file);
  EXPECT_EQ(summary["photometric_calibration"]["folder"], sequence.string());
  EXPECT_EQ(summary["photometric_calibration"]["held"], "both");
  std::ifstream calibration_file(out / "calibration" / "calibration.json");
  const auto calibration = nlohmann::json::parse(calibration_file);
  EXPECT_EQ(calibration["ambiguity_resolution"], "given calibration") << calibration.dump(2);

  const CommandResult missing = run_command(nirslam("run '" + sequence.string() + "' --mode calibrated "
                                                    "--photometric-calibration /no/such/calibration --out '" + out.string() + "'"));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("/no/such/calibration"), std::string::npos) << missing.output;

  // A folder whose files the pipeline refuses (here: no pcalib.txt) fails the run by name,
  // instead of a run that quietly computed image quality only.
  const fs::path empty = fresh_dir("given_calibration_empty");
  fs::create_directories(empty);
  const CommandResult refused = run_command(nirslam("run '" + sequence.string() + "' --mode calibrated --max-frames 5 "
                                                    "--photometric-calibration '" + empty.string() + "' --out '" + out.string() + "'"));
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_NE(refused.output.find((empty / "pcalib.txt").string()), std::string::npos) << refused.output;
}

TEST(RunCommand, UnknownModeIsRefused) {
  const CommandResult r = run_command(nirslam("run demo --mode dso --out '" + fresh_dir("badmode").string() + "'"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--mode"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nirslam::testing
