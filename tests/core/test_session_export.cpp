#include <zip.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/test_session_support.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/odometry/direct_odometry.hpp"
#include "nirslam/photometric/response_model.hpp"
#include "nirslam/session/odometry_output.hpp"
#include "nirslam/session/session_export.hpp"
#include "nirslam/session/session_recorder.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 20;

// A finished session with what a pipeline run leaves: the camera, a trajectory close to the
// ground truth (scaled: monocular), keyframes, a photometric calibration.
fs::path session_with_outputs(const std::string& name, int bit_depth) {
  const fs::path session = fresh_session_dir(name) / "s";
  RecorderOptions options;
  options.min_free_bytes_to_start = 0;
  options.min_free_bytes_while_recording = 0;
  RecordingSourceInfo source{"sim", "synthetic tunnel", 20.0,
                             std::make_shared<PinholeCamera>(64, 48, Eigen::Vector4d(50, 50, 31.5, 23.5))};
  SessionRecorder recorder(session, source, options);
  std::vector<PoseStamped> trajectory;
  for (int i = 0; i < kFrames; ++i) {
    const Frame frame = synthetic_frame(i, bit_depth);
    FrameAnnotations annotations;
    annotations.entropy_bits = 6.0 + 0.05 * i;
    recorder.record(frame, annotations);
    PoseStamped pose;
    pose.frame_index = i;
    pose.timestamp_s = frame.timestamp_s;
    pose.T_world_cam = SE3(frame.T_world_cam_truth->unit_quaternion(),
                           0.5 * frame.T_world_cam_truth->translation() + Eigen::Vector3d(0.001 * (i % 2), 0, 0));
    trajectory.push_back(pose);
  }
  write_trajectory_tum(session / session_files::kTrajectory, trajectory);
  write_keyframes(session / session_files::kKeyframes, {});
  recorder.add_output(session_files::kTrajectory);
  fs::create_directories(session / session_files::kCalibration);
  std::vector<double> inverse_response(256);
  for (int g = 0; g < 256; ++g) inverse_response[static_cast<std::size_t>(g)] = 255.0 * std::pow(g / 255.0, 1.6);
  write_pcalib(session / session_files::kCalibration / "pcalib.txt", inverse_response);
  cv::Mat vignette(48, 64, CV_32FC1);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x)
      vignette.at<float>(y, x) = 1.0f - 0.4f * static_cast<float>(((x - 32) * (x - 32) + (y - 24) * (y - 24)) / 1600.0);
  write_vignette_png(session / session_files::kCalibration / "vignette.png", vignette);
  recorder.stop("end of source");
  return session;
}

TEST(SessionExport, TheDatasetReadsBackThroughTheTumReaderBitForBit) {
  for (int bit_depth : {8, 16}) {
    const fs::path session = session_with_outputs(fmt::format("export_{}", bit_depth), bit_depth);
    const fs::path out = fresh_session_dir(fmt::format("export_out_{}", bit_depth)) / "dataset";
    const ExportSummary summary = export_session(session, out);
    EXPECT_EQ(summary.frames, kFrames);

    TumMonoVoReader reader(out);
    ASSERT_EQ(reader.info().frame_count, static_cast<std::size_t>(kFrames));
    ASSERT_TRUE(reader.calibration()) << "camera.txt travels with the images";
    EXPECT_DOUBLE_EQ(reader.camera()->fx(), 50.0);
    ASSERT_TRUE(reader.response_file());
    ASSERT_TRUE(reader.vignette_file());
    for (int i = 0; i < kFrames; ++i) {
      const std::optional<Frame> frame = reader.next();
      ASSERT_TRUE(frame);
      const Frame expected = synthetic_frame(i, bit_depth);
      EXPECT_TRUE(same_pixels(frame->image, expected.image)) << "frame " << i << ", " << bit_depth << " bit";
      EXPECT_NEAR(frame->timestamp_s, expected.timestamp_s, 1e-9);
      ASSERT_TRUE(frame->exposure_ms);
      EXPECT_NEAR(*frame->exposure_ms, *expected.exposure_ms, 1e-6);
    }
    EXPECT_FALSE(reader.next());
  }
}

TEST(SessionExport, WritesTrajectoryGroundTruthTablesPlotsAndTheReport) {
  const fs::path session = session_with_outputs("export_all", 8);
  const fs::path out = fresh_session_dir("export_all_out") / "dataset";
  ExportOptions options;
  options.archive = true;
  const ExportSummary summary = export_session(session, out, options);
  for (const char* file : {"trajectory.txt", "keyframes.txt", "groundtruth.txt", "frames.csv", "report.html",
                           "pcalib.txt", "vignette.png", "calibration/pcalib.txt"})
    EXPECT_TRUE(fs::exists(out / file)) << file;
  EXPECT_EQ(read_trajectory(out / "groundtruth.txt").size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(read_trajectory_segments(out / "trajectory.txt").front().size(), static_cast<std::size_t>(kFrames));
  EXPECT_NE(summary.evaluation.find("ATE RMSE"), std::string::npos) << summary.evaluation;

  for (const char* plot : {"report/entropy.png", "report/exposure.png", "report/photometric.png",
                           "report/trajectory.png", "report/error_heatmap.png"}) {
    const cv::Mat image = nirslam::read_image(out / plot, nirslam::ImageReadMode::Bgr);
    ASSERT_FALSE(image.empty()) << plot;
    cv::Mat grey;
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
    cv::Scalar mean, stddev;
    cv::meanStdDev(grey, mean, stddev);
    EXPECT_GT(stddev[0], 10.0) << plot << " is blank";
  }
  std::ifstream html_file(out / "report.html");
  std::stringstream html;
  html << html_file.rdbuf();
  for (const char* needle : {"<img src=\"report/entropy.png\"", "<img src=\"report/photometric.png\"",
                             "<img src=\"report/error_heatmap.png\"", "synthetic tunnel", "ATE RMSE"})
    EXPECT_NE(html.str().find(needle), std::string::npos) << needle;

  const std::vector<std::string> rows = [&] {
    std::ifstream in(out / "frames.csv");
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    return lines;
  }();
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(kFrames + 1));
  EXPECT_EQ(rows[1].rfind("00000,0,100.000000000,5.000000,2.000000,40.000000,6.000000,0", 0), 0u) << rows[1];

  ASSERT_TRUE(summary.archive);
  EXPECT_EQ(*summary.archive, fs::path(out.string() + ".zip"));
  int error = 0;
  zip_t* zip = zip_open(summary.archive->c_str(), ZIP_RDONLY, &error);
  ASSERT_NE(zip, nullptr);
  EXPECT_GE(zip_name_locate(zip, "dataset/images/00019.png", 0), 0);
  EXPECT_GE(zip_name_locate(zip, "dataset/report.html", 0), 0);
  EXPECT_GE(zip_name_locate(zip, "dataset/times.txt", 0), 0);
  zip_close(zip);
}

TEST(SessionExport, RefusesAnUnfinishedSessionAndANonEmptyOutput) {
  const fs::path session = session_with_outputs("export_refuse", 8);
  const fs::path out = fresh_session_dir("export_refuse_out");
  std::ofstream(out / "keep.txt") << "x";
  EXPECT_THROW(export_session(session, out), InputError);
  SessionMetadata metadata = read_session_metadata(session);
  metadata.state = SessionState::Recording;
  write_session_metadata(session, metadata);
  try {
    export_session(session, out / "new");
    FAIL() << "exported an unfinished session";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nirslam recover"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nirslam::testing
