// Simulated sequences on disk, read back through the project's own readers (TUM monoVO, DSO
// camera.txt, pcalib.txt, vignette.png), the power sweep, and write failures.

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "nirslam/camera/camera_io.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/photometric/response_model.hpp"
#include "nirslam/sim/sequence_writer.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/open_source.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

class SequenceWriterTest : public ::testing::Test {
protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() / ("nirslam_sim_" + std::string(info->name()) + "_" + std::to_string(std::random_device{}()));
  }
  void TearDown() override { fs::remove_all(root_); }
  fs::path root_;
};

SimulatorOptions six_small_frames(sim::SceneKind scene) {
  SimulatorOptions o;
  o.scene = scene;
  o.width = 96;
  o.height = 72;
  o.frames = 6;
  return o;
}

std::vector<std::string> lines_of(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

TEST_F(SequenceWriterTest, SequenceRoundTripsThroughTheProjectsReaders) {
  for (const SimCameraModel model : {SimCameraModel::Pinhole, SimCameraModel::Fov}) {
    SimulatorOptions o = six_small_frames(sim::SceneKind::Tunnel);
    o.camera_model = model;
    const fs::path folder = root_ / (model == SimCameraModel::Pinhole ? "pinhole" : "fov");
    SimulationOutput output;
    output.write_depth = true;
    output.contact_sheet = folder / "sheet.png";
    const SequenceSummary summary = write_simulated_sequence(o, folder, output);
    EXPECT_EQ(summary.images, 6);

    // The frames as TUM monoVO, with the same bytes, times and exposures as the simulator gives.
    ASSERT_EQ(detect_source_format(folder), SourceFormat::TumMonoVo);
    TumMonoVoReader reader(folder);
    ASSERT_TRUE(reader.calibration());
    const CameraModel& cam = *reader.camera();
    Simulator sim(o);
    EXPECT_EQ(cam.type(), sim.camera()->type());
    EXPECT_NEAR((cam.intrinsics() - sim.camera()->intrinsics()).norm(), 0.0, 1e-5);
    EXPECT_NEAR((cam.distortion() - sim.camera()->distortion()).norm(), 0.0, 1e-8);
    ASSERT_TRUE(reader.response_file() && reader.vignette_file());
    int count = 0;
    while (auto frame = reader.next()) {
      const auto truth = sim.next();
      ASSERT_TRUE(truth);
      EXPECT_EQ(cv::norm(frame->image, truth->frame.image, cv::NORM_INF), 0.0) << "frame " << count;
      EXPECT_NEAR(frame->timestamp_s, truth->frame.timestamp_s, 1e-9);
      ASSERT_TRUE(frame->exposure_ms);
      EXPECT_NEAR(*frame->exposure_ms, *truth->frame.exposure_ms, 1e-6);
      ++count;
    }
    EXPECT_EQ(count, 6);

    // The photometric calibration files.
    const std::vector<double> G = read_pcalib(*reader.response_file());
    const std::vector<double> G_true = o.response.inverse_table(256);
    for (std::size_t i = 0; i < 256; ++i) EXPECT_NEAR(G[i], G_true[i], 1e-6 * std::max(1.0, G_true[i]));
    const cv::Mat V = read_vignette_png(*reader.vignette_file());  // divided by its maximum, as DSO reads it
    double v_max = 0.0;
    cv::minMaxLoc(sim.vignette_map(), nullptr, &v_max);
    EXPECT_LT(cv::norm(V, sim.vignette_map() / v_max, cv::NORM_INF), 2.0 / 65535.0);

    // Ground truth: TUM trajectory and the JSON.
    const auto truth_lines = lines_of(folder / "groundtruth.txt");
    ASSERT_EQ(truth_lines.size(), 7u);  // header + 6
    std::istringstream first(truth_lines[1]);
    double t, tx, ty, tz, qx, qy, qz, qw;
    first >> t >> tx >> ty >> tz >> qx >> qy >> qz >> qw;
    const SE3 pose0 = sim.trajectory().pose(0.0);
    EXPECT_NEAR((Eigen::Vector3d(tx, ty, tz) - pose0.translation()).norm(), 0.0, 1e-8);
    EXPECT_NEAR(std::abs(Eigen::Quaterniond(qw, qx, qy, qz).dot(pose0.unit_quaternion())), 1.0, 1e-8);
    std::ifstream json_file(folder / "groundtruth.json");
    const auto j = nlohmann::json::parse(json_file);
    EXPECT_EQ(j["scene"]["kind"], "tunnel");
    EXPECT_EQ(j["scene"]["seed"], 1);
    EXPECT_EQ(j["response"]["inverse_response_grey"].size(), 256u);
    EXPECT_EQ(j["response"]["preset"], "gamma");
    EXPECT_EQ(j["exposure"]["mode"], "auto");
    EXPECT_EQ(j["frames"], 6);
    EXPECT_NEAR(j["vignette"]["coefficients"][0].get<double>(), -0.35, 1e-12);
    EXPECT_NEAR(j["illuminator"]["powers_w"][0].get<double>(), 50.0, 1e-12);
    const auto frames_csv = lines_of(folder / "frames.csv");
    ASSERT_EQ(frames_csv.size(), 7u);
    EXPECT_EQ(frames_csv[1].rfind("0,images/00000.png,0.000000000,", 0), 0u) << frames_csv[1];
    const cv::Mat depth = nirslam::read_image(folder / "depth" / "00003.png");
    EXPECT_EQ(depth.type(), CV_16UC1);
    const cv::Mat sheet = nirslam::read_image(folder / "sheet.png");
    EXPECT_FALSE(sheet.empty());
  }
}

std::string bytes_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

TEST_F(SequenceWriterTest, SameSeedWritesTheSameBytes) {
  SimulatorOptions o = six_small_frames(sim::SceneKind::Parking);
  o.frames = 4;
  write_simulated_sequence(o, root_ / "a");
  write_simulated_sequence(o, root_ / "b");
  for (const char* file : {"images/00000.png", "images/00003.png", "times.txt", "groundtruth.txt", "frames.csv",
                           "pcalib.txt", "vignette.png", "camera.txt", "groundtruth.json"})
    EXPECT_EQ(bytes_of(root_ / "a" / file), bytes_of(root_ / "b" / file)) << file;
  o.seed = 9;
  write_simulated_sequence(o, root_ / "c");
  EXPECT_NE(bytes_of(root_ / "a" / "images/00000.png"), bytes_of(root_ / "c" / "images/00000.png"));
}

TEST_F(SequenceWriterTest, CameraFileIsWhatDsoExpects) {
  SimulatorOptions o = six_small_frames(sim::SceneKind::Room);
  write_dso_camera_file(root_.string() + "_camera.txt", *make_sim_camera(o));
  const auto lines = lines_of(root_.string() + "_camera.txt");
  fs::remove(root_.string() + "_camera.txt");
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0].rfind("Pinhole ", 0), 0u);
  EXPECT_EQ(lines[0].substr(lines[0].size() - 2), " 0");
  EXPECT_EQ(lines[1], "96 72");
  EXPECT_EQ(lines[2], "none");
  EXPECT_EQ(lines[3], "96 72");
}

TEST_F(SequenceWriterTest, PowerSweepRendersOneViewpointAtEveryPower) {
  SimulatorOptions o = six_small_frames(sim::SceneKind::Room);
  o.exposure_mode = ExposureMode::Fixed;
  o.exposure_ms = 2.0;
  PowerSweepOptions sweep;
  sweep.powers_w = {0.0, 30.0, 60.0, 90.0};
  sweep.viewpoints = 2;
  const SequenceSummary summary = write_power_sweep(o, sweep, root_);
  EXPECT_EQ(summary.images, 8);
  const auto rows = lines_of(root_ / "sweep.csv");
  ASSERT_EQ(rows.size(), 9u);
  EXPECT_EQ(rows[0], "file,viewpoint,frame_index,timestamp_s,power_w,exposure_ms,gain,mean_grey");
  std::vector<double> greys;
  for (std::size_t i = 1; i <= 4; ++i) greys.push_back(std::stod(rows[i].substr(rows[i].rfind(',') + 1)));
  for (std::size_t i = 1; i < greys.size(); ++i) EXPECT_GT(greys[i], greys[i - 1]) << "power " << sweep.powers_w[i];
  EXPECT_LT(greys[0], 0.05);  // 0 W: only the faint ambient light
  // Still a TUM monoVO folder.
  TumMonoVoReader reader(root_);
  EXPECT_EQ(reader.info().frame_count, 8u);
}

TEST_F(SequenceWriterTest, FullDiskIsReportedWithTheFileName) {
  fs::create_directories(root_);
  fs::create_symlink("/dev/full", root_ / "times.txt");
  try {
    write_simulated_sequence(six_small_frames(sim::SceneKind::Room), root_);
    FAIL() << "writing to a full disk succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("times.txt"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nirslam
