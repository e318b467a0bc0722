// `nirslam eval`: the printed table, the JSON report and the heat map PNG on hand-made files, the
// real EuRoC ground truth against a 20 Hz trajectory, and bad input (the message names file and line).

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "app/cli_runner.hpp"
#include "core/test_eval_fixtures.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/sources/euroc_reader.hpp"
#include "text_contains.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;
using eval_testing::EvalFileTest;
using eval_testing::example_sim3;
using eval_testing::loop_trajectory;
using eval_testing::transformed;

using EvalCommand = EvalFileTest;


// Built with append: GCC 12 warns (-Wrestrict, a known false positive) on "'" + string + "'".
std::string quoted(const fs::path& p) {
  std::string text = "'";
  text.append(p.string());
  text.push_back('\'');
  return text;
}

// Ground truth at 200 Hz (TUM) and an estimate at 20 Hz, moved by a Sim(3) and noised by 2 cm RMS.
struct Pair {
  fs::path estimate, ground_truth;
};

Pair write_noisy_pair(const fs::path& root) {
  const Trajectory gt = loop_trajectory(6000, 30.0, 1403715274.302142);
  Trajectory est;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.02 / std::sqrt(3.0));
  for (std::size_t k = 0; k < gt.size(); k += 10) {
    TimedPose p = gt.poses[k];
    p.timestamp_s += 0.0015;
    p.T_world_cam = SE3(p.T_world_cam.unit_quaternion(),
                        p.T_world_cam.translation() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    est.poses.push_back(p);
  }
  const Pair files{root / "estimate.txt", root / "groundtruth.txt"};
  write_tum(files.estimate, transformed(est, example_sim3().inverse()));
  write_tum(files.ground_truth, gt);
  return files;
}

TEST_F(EvalCommand, PrintsTheTableAndWritesJsonAndAHeatMap) {
  const Pair files = write_noisy_pair(root_);
  const fs::path json_file = root_ / "eval.json", png = root_ / "heat.png";
  const CommandResult r = run_command(nirslam("eval " + quoted(files.estimate) + " " + quoted(files.ground_truth) +
                                              " --plot " + quoted(png) + " --json " + quoted(json_file)));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* part : {"600 of 600 estimated poses paired within 0.02 s", "Sim(3) on all 600 pairs, scale ",
                           "ATE [m]", "RPE 1 frame trans [m]", "RPE 1 frame rot [deg]", "RPE 1 m trans [%]",
                           "RPE 1 m rot [deg/m]", "rmse", "median"})
    EXPECT_TRUE(contains(r.output, part)) << part << "\n" << r.output;

  std::ifstream in(json_file);
  const nlohmann::json json = nlohmann::json::parse(in);
  EXPECT_EQ(json["association"]["pairs"], 600);
  EXPECT_NEAR(json["ate_m"]["rmse"].get<double>(), 0.02, 0.002);  // the injected noise comes back
  EXPECT_NEAR(json["alignment"]["scale"].get<double>(), 0.37, 0.002);

  const cv::Mat image = nirslam::read_image(png, nirslam::ImageReadMode::Bgr);
  ASSERT_FALSE(image.empty()) << r.output;
  EXPECT_EQ(image.cols, 1200);
  EXPECT_EQ(image.rows, 900);
  EXPECT_LT(fs::file_size(png), 200u * 1024u);
}

TEST_F(EvalCommand, Se3AlignFirstAndPlotSizeOptions) {
  const Pair files = write_noisy_pair(root_);
  const fs::path png = root_ / "small.png";
  const CommandResult r = run_command(nirslam("eval " + quoted(files.estimate) + " " + quoted(files.ground_truth) +
                                              " --align se3 --align-first 100 --rpe-distance 2 --plot-size 800x600 "
                                              "--plot " + quoted(png)));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "SE(3) on the first 100 of 600 pairs, scale fixed at 1")) << r.output;
  EXPECT_TRUE(contains(r.output, "the estimate is 170.")) << r.output;  // 1 / 0.37 - 1 = +170 %
  EXPECT_TRUE(contains(r.output, "RPE 2 m trans [%]")) << r.output;
  const cv::Mat image = nirslam::read_image(png, nirslam::ImageReadMode::Bgr);
  EXPECT_EQ(image.cols, 800);
  EXPECT_EQ(image.rows, 600);
  EXPECT_NE(run_command(nirslam("eval " + quoted(files.estimate) + " " + quoted(files.ground_truth) +
                                " --plot-size 100x10 --plot " + quoted(png)))
                .exit_code,
            0);
  EXPECT_NE(run_command(nirslam("eval " + quoted(files.estimate) + " " + quoted(files.ground_truth) + " --align affine"))
                .exit_code,
            0);
}

// The real 200 Hz EuRoC ground truth against a 20 Hz trajectory at the camera's timestamps (the
// ground-truth pose nearest each frame, written as TUM): 74 of the 95 frames lie in its span.
TEST_F(EvalCommand, RealEurocGroundTruthAgainstA20HzTrajectory) {
  const fs::path gt_file = eval_testing::kEuroc / "groundtruth_tum.txt";
  const Trajectory gt = read_trajectory(gt_file);
  const EurocReader camera(eval_testing::kEuroc);
  Trajectory est;
  for (const std::int64_t ns : camera.timestamps_ns()) {
    const double t = seconds_from_nanoseconds(ns);
    if (t < gt.poses.front().timestamp_s - 0.01) continue;
    const auto nearest = std::min_element(gt.poses.begin(), gt.poses.end(), [t](const TimedPose& a, const TimedPose& b) {
      return std::abs(a.timestamp_s - t) < std::abs(b.timestamp_s - t);
    });
    est.poses.push_back({t, nearest->T_world_cam});
  }
  const fs::path est_file = root_ / "cam_rate.txt";
  write_tum(est_file, est);
  const CommandResult r = run_command(nirslam("eval " + quoted(est_file) + " " + quoted(gt_file) + " --align se3"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "(TUM, 840 poses over 4.195 s)")) << r.output;
  EXPECT_TRUE(contains(r.output, "74 of 74 estimated poses paired")) << r.output;
  EXPECT_TRUE(contains(r.output, "RPE 1 m segments")) << "under 3 mm of motion: no 1 m segment\n" << r.output;
}

TEST_F(EvalCommand, KittiInputsGetTimestampsFromARate) {
  std::string kitti;
  const Trajectory gt = loop_trajectory(100, 10.0, 0.0);
  for (const TimedPose& p : gt.poses) {
    const Eigen::Matrix4d m = p.T_world_cam.matrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) kitti += std::to_string(m(r, c)) + (r == 2 && c == 3 ? "\n" : " ");
  }
  const fs::path est = write("est_kitti.txt", kitti), gt_file = write("gt_kitti.txt", kitti);
  const CommandResult r = run_command(nirslam("eval " + quoted(est) + " " + quoted(gt_file) + " --kitti-rate 10"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "KITTI, 100 poses over 9.900 s")) << r.output;
  EXPECT_TRUE(contains(r.output, "100 of 100 estimated poses paired")) << r.output;
}

TEST_F(EvalCommand, BadInputGetsAClearErrorAndExitCode1) {
  const fs::path gt = write("gt.txt", "1.0 0 0 0 0 0 0 1\n1.1 1 0 0 0 0 0 1\n1.2 1 1 0 0 0 0 1\n1.3 0 1 0 0 0 0 1\n");
  struct Case {
    std::string estimate;
    std::string message;
  };
  const Case cases[] = {
      {"1.0 0 0 0 0 0 0 1\n1.1 nan 0 0 0 0 0 1\n", "est.txt:2: column 2 (tx) is 'nan'"},
      {"1.0 0 0 0 0 0 0 1\n1.2 1 1 0 0 0 0 1\n1.1 1 0 0 0 0 0 1\n", "est.txt:3: timestamp 1.100000 is before line 2's"},
      {"5.0 0 0 0 0 0 0 1\n5.1 1 0 0 0 0 0 1\n5.2 1 1 0 0 0 0 1\n", "est.txt: no overlap in time with the ground truth"},
      {"1.0 0 0 0 0 0 0 1\n1.1 1 0 0 0 0 0 1\n", "est.txt: only 2 pose(s) pair up"},
      {"1.0 0 0 0 0 0 0 1\n1.1 1 0 0 0 0 0 1\n1.2 2 0 0 0 0 0 1\n", "lie on one straight line"},
      {"1 2 3\n", "est.txt:1: cannot tell the trajectory format from 3 fields"},
  };
  for (const Case& c : cases) {
    const fs::path est = write("est.txt", c.estimate);
    const CommandResult r = run_command(nirslam("eval " + quoted(est) + " " + quoted(gt)));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_TRUE(contains(r.output, c.message)) << "expected: " << c.message << "\n" << r.output;
  }
  const CommandResult missing = run_command(nirslam("eval " + quoted(root_ / "none.txt") + " " + quoted(gt)));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_TRUE(contains(missing.output, "none.txt")) << missing.output;
  const CommandResult unwritable = run_command(nirslam("eval " + quoted(gt) + " " + quoted(gt) + " --plot " +
                                                       quoted(root_ / "no" / "dir" / "x.png")));
  EXPECT_EQ(unwritable.exit_code, 1);
  EXPECT_TRUE(contains(unwritable.output, "x.png")) << unwritable.output;
}

}  // namespace
}  // namespace nirslam::testing
