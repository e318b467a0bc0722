// Trajectory readers and writer: each format on hand-made files written at test time, format
// auto-detection, every bad-input case (the error names file and line), and the real EuRoC ground
// truth of the micro sequence.

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/test_eval_fixtures.hpp"
#include "nirslam/camera/camera_io.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "text_contains.hpp"

namespace nirslam {
namespace {

using eval_testing::EvalFileTest;
using eval_testing::kEuroc;
namespace fs = std::filesystem;

using TrajectoryIo = EvalFileTest;

// Runs `read` and returns the InputError it throws (fails the test when it throws none).
template <typename F>
InputError expect_input_error(F&& read) {
  try {
    read();
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError thrown";
  return InputError(fs::path(), "none");
}


TEST_F(TrajectoryIo, ReadsTumWithCommentsAndBlankLines) {
  const fs::path file = write("est.txt",
                              "# timestamp tx ty tz qx qy qz qw\n"
                              "\n"
                              "1.0 1 2 3 0 0 0 1\n"
                              "  1.5\t4 5 6 0 0 0.7071067811865476 0.7071067811865476  \r\n"
                              "# a comment in the middle\n"
                              "2.0 -1 -2 -3 1 0 0 0\n");
  const Trajectory t = read_trajectory(file);
  EXPECT_EQ(t.format, TrajectoryFormat::Tum);
  EXPECT_FALSE(t.position_only);
  EXPECT_EQ(t.source, file);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_DOUBLE_EQ(t.poses[1].timestamp_s, 1.5);
  EXPECT_EQ(t.poses[1].T_world_cam.translation(), Eigen::Vector3d(4, 5, 6));
  // qx qy qz qw: 90 degrees about z maps x to y.
  EXPECT_NEAR((t.poses[1].T_world_cam.rotation_matrix() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 0.0,
              1e-12);
  // 180 degrees about x.
  EXPECT_NEAR((t.poses[2].T_world_cam.rotation_matrix() * Eigen::Vector3d::UnitY() + Eigen::Vector3d::UnitY()).norm(), 0.0,
              1e-12);
}

TEST_F(TrajectoryIo, ReadsKittiWithTimesFileRateOrFrameIndex) {
  // Pose 1: 90 degrees about z, at (1, 2, 3). KITTI rows: r11 r12 r13 tx / r21 ... / r31 ...
  const fs::path poses = write("00.txt",
                               "1 0 0 0 0 1 0 0 0 0 1 0\n"
                               "0 -1 0 1 1 0 0 2 0 0 1 3\n"
                               "1.000000e+00 0 0 5.0 0 1 0 0 0 0 1 0\n");
  const fs::path times = write("times.txt", "0.000000e+00\n1.036018e-01\n2.072036e-01\n");

  TrajectoryReadOptions with_times;
  with_times.kitti.times_file = times;
  const Trajectory a = read_trajectory(poses, with_times);
  EXPECT_EQ(a.format, TrajectoryFormat::Kitti);
  ASSERT_EQ(a.size(), 3u);
  EXPECT_DOUBLE_EQ(a.poses[1].timestamp_s, 0.1036018);
  EXPECT_EQ(a.poses[1].T_world_cam.translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_NEAR((a.poses[1].T_world_cam.rotation_matrix() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 0.0,
              1e-12);

  TrajectoryReadOptions with_rate;
  with_rate.kitti.rate_hz = 10.0;
  const Trajectory b = read_trajectory(poses, with_rate);
  EXPECT_DOUBLE_EQ(b.poses[2].timestamp_s, 0.2);

  const Trajectory c = read_trajectory(poses);  // frame index as seconds
  EXPECT_DOUBLE_EQ(c.poses[0].timestamp_s, 0.0);
  EXPECT_DOUBLE_EQ(c.poses[2].timestamp_s, 2.0);

  // TUM monoVO times.txt: "id timestamp exposure".
  const fs::path monovo = write("monovo_times.txt", "0 1.5 10.0\n1 1.55 10.0\n2 1.6 12.5\n");
  TrajectoryReadOptions with_monovo;
  with_monovo.kitti.times_file = monovo;
  EXPECT_DOUBLE_EQ(read_trajectory(poses, with_monovo).poses[2].timestamp_s, 1.6);
}

TEST_F(TrajectoryIo, ReadsEurocGroundTruthCsvWithQuaternionWFirst) {
  const fs::path file = write(
      "data.csv",
      "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
      "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], "
      "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n"
      "1403715273262142976,0.878612,2.142470,0.947262,0.060514,-0.828459,-0.058956,-0.553641,0.0,0.0,0.0,-0.002,0.02,"
      "0.07,-0.01,0.1,0.08\n"
      "1403715273267142976,0.9,2.2,1.0,0.7071067811865476,0,0,0.7071067811865476,0,0,0,0,0,0,0,0,0\n");
  const Trajectory t = read_trajectory(file);
  EXPECT_EQ(t.format, TrajectoryFormat::EurocCsv);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_NEAR(t.poses[0].timestamp_s, 1403715273.262142976, 1e-6);
  EXPECT_NEAR(t.poses[1].timestamp_s - t.poses[0].timestamp_s, 0.005, 3e-7);  // doubles at 1.4e9 s: 0.24 us steps
  EXPECT_EQ(t.poses[0].T_world_cam.translation(), Eigen::Vector3d(0.878612, 2.142470, 0.947262));
  const Eigen::Quaterniond q = t.poses[0].T_world_cam.unit_quaternion();
  EXPECT_NEAR(std::abs(q.w()), 0.060514, 1e-5);  // w is column 5, not column 8
  EXPECT_NEAR(std::abs(q.x()), 0.828459, 1e-5);
  // Row 2: 90 degrees about z.
  EXPECT_NEAR((t.poses[1].T_world_cam.rotation_matrix() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 0.0,
              1e-12);
}

TEST_F(TrajectoryIo, ReadsTotalStationLogAsPositionOnly) {
  const fs::path blanks = write("ts60.txt", "# Leica TS60, prism on the rig\n10.0 100.5 200.25 50.125\n10.1 100.6 200.3 50.1\n"
                                            "10.2 100.7 200.35 50.0\n");
  const Trajectory t = read_trajectory(blanks);
  EXPECT_EQ(t.format, TrajectoryFormat::TotalStation);
  EXPECT_TRUE(t.position_only);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t.poses[0].T_world_cam.translation(), Eigen::Vector3d(100.5, 200.25, 50.125));
  EXPECT_TRUE(t.poses[0].T_world_cam.unit_quaternion().isApprox(Eigen::Quaterniond::Identity()));

  const fs::path commas = write("ts60.csv", "10.0, 100.5, 200.25, 50.125\n10.1,100.6,200.3,50.1\n");
  const Trajectory c = read_trajectory(commas);
  EXPECT_EQ(c.format, TrajectoryFormat::TotalStation);
  EXPECT_EQ(c.size(), 2u);
}

TEST_F(TrajectoryIo, DetectsEachFormatAndHonoursAnExplicitOne) {
  EXPECT_EQ(detect_trajectory_format(write("a", "# x\n1 0 0 0 0 0 0 1\n")), TrajectoryFormat::Tum);
  EXPECT_EQ(detect_trajectory_format(write("b", "1 0 0 0 0 1 0 0 0 0 1 0\n")), TrajectoryFormat::Kitti);
  EXPECT_EQ(detect_trajectory_format(write("c", "1 2 3 4\n")), TrajectoryFormat::TotalStation);
  EXPECT_EQ(detect_trajectory_format(write("d", "1,0,0,0,1,0,0,0\n")), TrajectoryFormat::EurocCsv);
  // An explicit format is checked line by line: a TUM file read as total station fails on line 1.
  const fs::path tum = write("e", "1 0 0 0 0 0 0 1\n");
  const InputError e = expect_input_error([&] { read_trajectory(tum, TrajectoryFormat::TotalStation); });
  EXPECT_EQ(e.line(), 1);
  EXPECT_TRUE(contains(e.what(), "expected 4 fields")) << e.what();
  EXPECT_EQ(trajectory_format_from_string("total-station"), TrajectoryFormat::TotalStation);
  EXPECT_EQ(trajectory_format_from_string("euroc"), TrajectoryFormat::EurocCsv);
  EXPECT_FALSE(trajectory_format_from_string("csv"));
}

TEST_F(TrajectoryIo, WriteTumRoundTripsAndRefusesPositionOnly) {
  Trajectory t = eval_testing::loop_trajectory(50, 5.0, 1403715274.302142);
  const fs::path file = root_ / "out.txt";
  write_tum(file, t);
  const Trajectory back = read_trajectory(file);
  ASSERT_EQ(back.size(), t.size());
  for (std::size_t k = 0; k < t.size(); ++k) {
    EXPECT_NEAR(back.poses[k].timestamp_s, t.poses[k].timestamp_s, 1e-6);
    EXPECT_NEAR((back.poses[k].T_world_cam.translation() - t.poses[k].T_world_cam.translation()).norm(), 0.0, 1e-8);
    EXPECT_NEAR(back.poses[k].T_world_cam.unit_quaternion().angularDistance(t.poses[k].T_world_cam.unit_quaternion()), 0.0,
                1e-8);
  }
  t.position_only = true;
  EXPECT_THROW(write_tum(file, t), std::invalid_argument);
  write_positions(root_ / "positions.txt", t);
  const Trajectory positions = read_trajectory(root_ / "positions.txt");
  EXPECT_TRUE(positions.position_only);
  EXPECT_EQ(positions.size(), t.size());
  EXPECT_THROW(write_tum(root_ / "no" / "such" / "folder.txt", back), InputError);
}

// --- Bad input: each case names the file and the line.

TEST_F(TrajectoryIo, NanAndInfinityAreRejectedNamingLineAndColumn) {
  const fs::path nan_file = write("nan.txt", "1 0 0 0 0 0 0 1\n2 0 nan 0 0 0 0 1\n");
  const InputError e = expect_input_error([&] { read_trajectory(nan_file); });
  EXPECT_EQ(e.file(), nan_file);
  EXPECT_EQ(e.line(), 2);
  EXPECT_TRUE(contains(e.what(), "column 3 (ty)")) << e.what();
  EXPECT_TRUE(contains(e.what(), "NaN")) << e.what();
  const fs::path inf_file = write("inf.txt", "1 0 0 0\n2 0 0 -inf\n");
  EXPECT_EQ(expect_input_error([&] { read_trajectory(inf_file); }).line(), 2);
  const fs::path nan_stamp = write("nan_stamp.csv", "1,0,0,0,1,0,0,0\nNaN,0,0,0,1,0,0,0\n");
  const InputError s = expect_input_error([&] { read_trajectory(nan_stamp); });
  EXPECT_EQ(s.line(), 2);
  EXPECT_TRUE(contains(s.what(), "NaN")) << s.what();
}

TEST_F(TrajectoryIo, UnsortedAndDuplicateTimestampsAreRejectedNamingTheLine) {
  const fs::path unsorted = write("unsorted.txt", "# header\n1.0 0 0 0 0 0 0 1\n3.0 0 0 0 0 0 0 1\n\n2.0 0 0 0 0 0 0 1\n");
  const InputError e = expect_input_error([&] { read_trajectory(unsorted); });
  EXPECT_EQ(e.line(), 5);
  EXPECT_TRUE(contains(e.what(), "must be sorted")) << e.what();
  EXPECT_TRUE(contains(e.what(), "line 3")) << e.what();
  const fs::path duplicate = write("dup.txt", "1.0 0 0 0\n1.0 1 0 0\n");
  const InputError d = expect_input_error([&] { read_trajectory(duplicate); });
  EXPECT_EQ(d.line(), 2);
  EXPECT_TRUE(contains(d.what(), "duplicate timestamp")) << d.what();
  // Nanosecond stamps out of order in a EuRoC CSV, and in a KITTI times file.
  const fs::path euroc = write("e.csv", "2000,0,0,0,1,0,0,0\n1000,0,0,0,1,0,0,0\n");
  EXPECT_EQ(expect_input_error([&] { read_trajectory(euroc); }).line(), 2);
  const fs::path poses = write("k.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n");
  const fs::path times = write("t.txt", "0.2\n0.1\n");
  TrajectoryReadOptions options;
  options.kitti.times_file = times;
  const InputError k = expect_input_error([&] { read_trajectory(poses, options); });
  EXPECT_EQ(k.file(), times);
  EXPECT_EQ(k.line(), 2);
}

TEST_F(TrajectoryIo, MalformedLinesAreNamed) {
  struct Case {
    std::string text;
    int line;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", 2, "expected 8 fields"},
      {"1 0 0 0 0 0 0 1\n2 0 0 zero 0 0 0 1\n", 2, "'zero' is not a number"},
      {"1 2 3 4 5\n", 1, "cannot tell the trajectory format from 5 fields"},
      {"1 0 0 0 0 0 0 0\n", 1, "quaternion is zero"},
      {"1 0 0 0 0 0 0 2\n", 1, "norm is 2"},
      {"1 0 0 0 0 2 0 0 0 0 1 0\n", 1, "not a rotation"},
      {"1.5,0,0,0,1,0,0,0\n", 1, "not an integer number of nanoseconds"},
      {"1,0,,0,1,0,0,0\n", 1, "column 3 (p_y) is empty"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const fs::path file = write("case" + std::to_string(i), cases[i].text);
    const InputError e = expect_input_error([&] { read_trajectory(file); });
    EXPECT_EQ(e.file(), file);
    EXPECT_EQ(e.line(), cases[i].line) << cases[i].text;
    EXPECT_TRUE(contains(e.what(), cases[i].message)) << e.what();
  }
}

TEST_F(TrajectoryIo, EmptyMissingAndMismatchedFilesAreNamed) {
  const fs::path empty = write("empty.txt", "# only a header\n\n");
  EXPECT_TRUE(contains(expect_input_error([&] { read_trajectory(empty); }).what(), "holds no poses"));
  const fs::path missing = root_ / "missing.txt";
  const InputError m = expect_input_error([&] { read_trajectory(missing); });
  EXPECT_EQ(m.file(), missing);
  EXPECT_TRUE(contains(m.what(), "does not exist"));
  EXPECT_TRUE(contains(expect_input_error([&] { read_trajectory(root_); }).what(), "is a folder"));

  const fs::path poses = write("k.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n");
  TrajectoryReadOptions options;
  options.kitti.times_file = write("t.txt", "0.1\n0.2\n0.3\n");
  const InputError k = expect_input_error([&] { read_trajectory(poses, options); });
  EXPECT_TRUE(contains(k.what(), "lists 3 timestamps")) << k.what();
  EXPECT_TRUE(contains(k.what(), "2 poses")) << k.what();
}

TEST(TrajectoryValidation, InMemoryTrajectoriesAreCheckedLikeFiles) {
  Trajectory t = eval_testing::loop_trajectory(10, 1.0);
  EXPECT_NO_THROW(validate_trajectory(t));
  Trajectory unsorted = t;
  std::swap(unsorted.poses[3], unsorted.poses[4]);
  try {
    validate_trajectory(unsorted, "simulated estimate");
    ADD_FAILURE() << "unsorted accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), fs::path("simulated estimate"));
    EXPECT_EQ(e.field(), "pose 4");
  }
  Trajectory nan = t;
  nan.poses[7].T_world_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, std::nan(""), 0));
  EXPECT_THROW(validate_trajectory(nan), InputError);
  EXPECT_THROW(validate_trajectory(Trajectory{}), InputError);
}

// The real ground truth of the micro EuRoC sequence: 840 lines of TUM at 200 Hz.
TEST(TrajectoryIoRealData, EurocMicroGroundTruthParses) {
  const fs::path file = kEuroc / "groundtruth_tum.txt";
  const Trajectory gt = read_trajectory(file);
  EXPECT_EQ(gt.format, TrajectoryFormat::Tum);
  ASSERT_EQ(gt.size(), 840u);
  EXPECT_NEAR(gt.poses.front().timestamp_s, 1403715274.30214, 1e-5);
  EXPECT_NEAR(gt.poses.back().timestamp_s, 1403715278.49714, 1e-5);
  std::vector<double> steps;
  for (std::size_t k = 1; k < gt.size(); ++k) steps.push_back(gt.poses[k].timestamp_s - gt.poses[k - 1].timestamp_s);
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
  EXPECT_NEAR(steps[steps.size() / 2], 0.005, 1e-5);  // 200 Hz
  EXPECT_EQ(gt.poses.front().T_world_cam.translation(), Eigen::Vector3d(0.878612, 2.142470, 0.947262));

  // Camera pose = body pose * T_BS (mav0/cam0/sensor.yaml).
  const EurocCameraSensor sensor = read_euroc_sensor_yaml(kEuroc / "mav0/cam0/sensor.yaml");
  const SE3 T_body_cam(Eigen::Matrix3d(sensor.T_body_sensor.topLeftCorner<3, 3>()),
                       Eigen::Vector3d(sensor.T_body_sensor.topRightCorner<3, 1>()));
  const Trajectory cam = transform_body_to_camera(gt, T_body_cam);
  const SE3& body = gt.poses.front().T_world_cam;
  const Eigen::Vector3d expected = body.translation() + body.rotation_matrix() * T_body_cam.translation();
  EXPECT_NEAR((cam.poses.front().T_world_cam.translation() - expected).norm(), 0.0, 1e-12);
  EXPECT_NEAR((cam.poses.front().T_world_cam.translation() - body.translation()).norm(), T_body_cam.translation().norm(),
              1e-12);  // the lever arm, about 7 cm
}

}  // namespace
}  // namespace nirslam
