// What a run writes about the odometry: TUM trajectory with segment markers that read back split,
// keyframes, and a binary PLY whose header and size match its points.

#include <filesystem>
#include <fstream>
#include <cstring>
#include <string>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/session/odometry_output.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

fs::path temp_file(const std::string& name) { return fs::temp_directory_path() / ("nirslam_odometry_output_" + name); }

std::vector<PoseStamped> two_segments() {
  std::vector<PoseStamped> poses;
  for (int i = 0; i < 6; ++i) {
    PoseStamped p;
    p.frame_index = i;
    p.timestamp_s = 0.1 * i;
    p.segment = i < 4 ? 0 : 1;
    p.T_world_cam = SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d::UnitY())), Eigen::Vector3d(i, 0.5 * i, 0.0));
    poses.push_back(p);
  }
  return poses;
}

TEST(OdometryOutput, TrajectoryReadsBackSplitAtItsSegments) {
  const fs::path file = temp_file("trajectory.txt");
  const auto poses = two_segments();
  write_trajectory_tum(file, poses);
  const std::vector<Trajectory> segments = read_trajectory_segments(file);
  ASSERT_EQ(segments.size(), 2u);
  ASSERT_EQ(segments[0].size(), 4u);
  ASSERT_EQ(segments[1].size(), 2u);
  EXPECT_NEAR(segments[1].poses[0].timestamp_s, 0.4, 1e-9);
  EXPECT_NEAR((segments[1].poses[1].T_world_cam.translation() - poses[5].T_world_cam.translation()).norm(), 0.0, 1e-8);
  EXPECT_NEAR(segments[0].poses[2].T_world_cam.unit_quaternion().angularDistance(poses[2].T_world_cam.unit_quaternion()), 0.0,
              1e-8);
  // Any TUM reader sees one trajectory: the markers are comments.
  EXPECT_EQ(read_trajectory(file).size(), 6u);
  fs::remove(file);
}

TEST(OdometryOutput, MalformedTrajectoryLineIsNamed) {
  const fs::path file = temp_file("bad_trajectory.txt");
  std::ofstream(file) << "# segment 0\n0.0 0 0 0 0 0 0 1\n0.1 0 0 zero 0 0 0 1\n";
  try {
    read_trajectory_segments(file);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("3"), std::string::npos) << "names line 3: " << e.what();
  }
  fs::remove(file);
}

TEST(OdometryOutput, KeyframesListTheirSegmentAndBrightness) {
  const fs::path file = temp_file("keyframes.txt");
  KeyframeState k;
  k.frame_index = 42;
  k.timestamp_s = 1.5;
  k.segment = 1;
  k.affine_a = 0.25;
  k.affine_b = -3.0;
  k.marginalised = true;
  write_keyframes(file, {k});
  std::ifstream in(file);
  std::string header;
  std::string line;
  std::getline(in, header);
  std::getline(in, line);
  EXPECT_EQ(header.rfind("# frame_index timestamp segment marginalised affine_a affine_b", 0), 0u);
  EXPECT_EQ(line.rfind("42 1.500000000 1 1 0.250000 -3.000000 0.000000000 0.000000000 0.000000000 ", 0), 0u) << line;
  fs::remove(file);
}

TEST(OdometryOutput, PlyHeaderMatchesItsBinaryBody) {
  const fs::path file = temp_file("points.ply");
  std::vector<MapPoint> points(3);
  points[1].p_world = Eigen::Vector3d(1.0, -2.0, 3.5);
  points[1].intensity = 200.0f;
  points[1].active = true;
  write_points_ply(file, points);
  std::ifstream in(file, std::ios::binary);
  std::string bytes(fs::file_size(file), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(in);
  const std::string end = "end_header\n";
  const auto body = bytes.find(end);
  ASSERT_NE(body, std::string::npos);
  EXPECT_NE(bytes.find("element vertex 3\n"), std::string::npos);
  EXPECT_NE(bytes.find("format binary_little_endian 1.0\n"), std::string::npos);
  const std::size_t stride = 3 * sizeof(float) + 2;
  ASSERT_EQ(bytes.size() - body - end.size(), 3 * stride);
  float xyz[3];
  std::memcpy(xyz, bytes.data() + body + end.size() + stride, sizeof(xyz));
  EXPECT_FLOAT_EQ(xyz[0], 1.0f);
  EXPECT_FLOAT_EQ(xyz[1], -2.0f);
  EXPECT_FLOAT_EQ(xyz[2], 3.5f);
  EXPECT_EQ(static_cast<unsigned char>(bytes[body + end.size() + stride + 12]), 200);
  EXPECT_EQ(static_cast<unsigned char>(bytes[body + end.size() + stride + 13]), 1);
  fs::remove(file);
}

TEST(OdometryOutput, UnwritableFileIsNamed) {
  try {
    write_trajectory_tum("/no/such/folder/trajectory.txt", two_segments());
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/no/such/folder/trajectory.txt"), std::string::npos);
  }
}

}  // namespace
}  // namespace nirslam
