// End-to-end runs of the direct odometry: simulated sequences against ground truth (ATE after
// Sim(3) alignment), the real EuRoC micro set (camera at rest) and the ViSP hand-held cube
// sequence. Excluded from the sanitizer run (suite name OdometrySequence*). Set
// NIRSLAM_ODOMETRY_VERBOSE=1 to print every frame's status.

#include <cstdlib>
#include <functional>
#include <filesystem>
#include <iostream>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/camera/undistorter.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "nirslam/odometry/direct_odometry.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/open_source.hpp"

namespace nirslam {
namespace {

bool verbose() { return std::getenv("NIRSLAM_ODOMETRY_VERBOSE") != nullptr; }

OdometryFrame to_odometry_frame(const Frame& frame, std::optional<double> exposure = std::nullopt) {
  OdometryFrame f;
  f.frame_index = frame.index;
  f.timestamp_s = frame.timestamp_s;
  const double scale = frame.image.depth() == CV_16U ? 255.0 / frame.max_value() : 1.0;
  frame.image.convertTo(f.image, CV_32F, scale);
  f.exposure = exposure;
  f.illuminator_power_w = frame.illuminator_power_w;
  return f;
}

void log_result(const OdometryResult& r) {
  if (!verbose()) return;
  std::cout << r.frame_index << " " << to_string(r.status) << (r.is_keyframe ? " KF" : "") << " seg " << r.segment
            << " rms " << r.residual_rms << " n " << r.residual_count << " a " << r.affine_a << " b " << r.affine_b
            << " t " << r.timings.total_ms << " ms";
  if (r.T_world_cam) std::cout << " p " << r.T_world_cam->translation().transpose();
  if (!r.message.empty()) std::cout << " (" << r.message << ")";
  std::cout << "\n";
}

struct SequenceOutcome {
  double ate_rmse_m = 0.0;
  double path_length_m = 0.0;
  int frames = 0;
  int posed = 0;
  int lost = 0;
  double mean_ms = 0.0;
};

SequenceOutcome run_simulated(sim::SceneKind scene, double power_w, int frames, bool corrected,
                              const std::function<void(SimulatorOptions&)>& tweak = {}) {
  SimulatorOptions o;
  o.scene = scene;
  o.powers_w = {power_w};
  o.frames = frames;
  o.width = 640;
  o.height = 480;
  o.supersampling = 1;
  if (tweak) tweak(o);
  Simulator simulator(o);
  const auto camera = make_sim_camera(o);
  const PinholeCamera pinhole(camera->width(), camera->height(), camera->intrinsics());
  OdometryOptions options;
  if (const char* w = std::getenv("NIRSLAM_ODOMETRY_WINDOW")) options.window_size = std::atoi(w);
  if (const char* w = std::getenv("NIRSLAM_ODOMETRY_ITER")) options.window_iterations = std::atoi(w);
  if (const char* w = std::getenv("NIRSLAM_ODOMETRY_PARALLAX")) options.init_min_parallax_px = std::atof(w);
  DirectOdometry odometry(pinhole, options);
  Trajectory ground_truth;
  SequenceOutcome out;
  double total_ms = 0.0;
  std::vector<float> G;
  if (corrected) {
    const auto table = o.response.inverse_table(256);
    G.assign(table.begin(), table.end());
  }
  while (auto f = simulator.next()) {
    ground_truth.poses.push_back({f->frame.timestamp_s, f->T_world_cam});
    OdometryFrame frame = to_odometry_frame(f->frame);
    if (corrected) {
      // G(I) / V with the simulator's known response and vignetting, and the exposure ratio.
      for (int y = 0; y < frame.image.rows; ++y) {
        float* row = frame.image.ptr<float>(y);
        const float* v = simulator.vignette_map().ptr<float>(y);
        for (int x = 0; x < frame.image.cols; ++x) row[x] = G[static_cast<std::size_t>(row[x])] / v[x];
      }
      frame.exposure = *f->frame.exposure_ms * f->frame.gain.value_or(1.0) / o.exposure_ms;
    }
    if (const char* b = std::getenv("NIRSLAM_ODOMETRY_BLUR")) cv::GaussianBlur(frame.image, frame.image, cv::Size(0, 0), std::atof(b));
    const OdometryResult r = odometry.process(frame);
    log_result(r);
    total_ms += r.timings.total_ms;
    ++out.frames;
    out.lost += r.status == TrackingStatus::Lost ? 1 : 0;
  }
  Trajectory estimate;
  for (const auto& p : odometry.trajectory()) estimate.poses.push_back({p.timestamp_s, p.T_world_cam});
  if (verbose()) {
    const auto traj = odometry.trajectory();
    const SE3 e0 = traj[0].T_world_cam;
    const SE3 g0 = ground_truth.poses[static_cast<std::size_t>(traj[0].frame_index)].T_world_cam;
    for (std::size_t i = 1; i < traj.size() && i < 60; i += 3) {
      const SE3 e = e0.inverse() * traj[i].T_world_cam;
      const SE3 g = g0.inverse() * ground_truth.poses[static_cast<std::size_t>(traj[i].frame_index)].T_world_cam;
      const double angle_err = (e.rotation_matrix() * g.rotation_matrix().transpose()).trace();
      std::cout << "rel " << traj[i].frame_index << " rot est " << so3_log(e.rotation_matrix()).transpose()
                << " gt " << so3_log(g.rotation_matrix()).transpose() << " | tdir est "
                << e.translation().normalized().transpose() << " gt " << g.translation().normalized().transpose()
                << " ratio " << e.translation().norm() / g.translation().norm() << " (" << angle_err << ")\n";
    }
  }
  out.posed = static_cast<int>(estimate.poses.size());
  out.mean_ms = total_ms / std::max(1, out.frames);
  const EvaluationResult e = evaluate(estimate, ground_truth);
  out.ate_rmse_m = e.ate_m.rmse;
  out.path_length_m = e.ground_truth_path_length_m;
  if (verbose()) {
    std::cout << "scale " << e.alignment.transform.scale << "\n";
    for (std::size_t i = 0; i < e.position_errors_m.size(); i += 10)
      std::cout << "err " << i << " " << e.position_errors_m[i] << " est " << e.estimate_positions_aligned[i].transpose()
                << " gt " << e.ground_truth_positions[i].transpose() << "\n";
  }
  std::cout << to_string(scene) << " " << power_w << " W" << (corrected ? " corrected" : " raw") << ": ATE "
            << out.ate_rmse_m << " m over " << out.path_length_m << " m ("
            << 100.0 * out.ate_rmse_m / std::max(1e-9, out.path_length_m) << " %), " << out.posed << "/" << out.frames
            << " frames posed, " << out.lost << " lost, " << odometry.keyframes().size() << " keyframes, "
            << out.mean_ms << " ms/frame\n";
  return out;
}

TEST(OdometrySequence, RoomTracksWithinOnePercentOfPathLength) {
  const auto r = run_simulated(sim::SceneKind::Room, 50.0, 300, false);
  EXPECT_EQ(r.lost, 0);
  EXPECT_GE(r.posed, r.frames - 15);
  EXPECT_LT(r.ate_rmse_m, 0.01 * r.path_length_m);
}

TEST(OdometrySequenceDebug, Variant) {
  const char* v = std::getenv("NIRSLAM_ODOMETRY_VARIANT");
  const std::string variant = v ? v : "";
  sim::SceneKind scene = sim::SceneKind::Room;
  if (variant.find("tunnel") != std::string::npos) scene = sim::SceneKind::Tunnel;
  if (variant.find("outdoor") != std::string::npos) scene = sim::SceneKind::Outdoor;
  if (variant.find("parking") != std::string::npos) scene = sim::SceneKind::Parking;
  run_simulated(scene, 50.0, 150, variant.find("corr") != std::string::npos, [&](SimulatorOptions& o) {
    if (variant.find("nonoise") != std::string::npos) o.noise = false;
    if (variant.find("fixed") != std::string::npos) o.exposure_mode = ExposureMode::Fixed;
    if (variant.find("novig") != std::string::npos) o.vignette = VignetteModel{Eigen::Vector3d::Zero()};
    if (variant.find("robot") != std::string::npos) o.motion = sim::MotionKind::Robot;
    if (variant.find("ambient") != std::string::npos) {
      o.powers_w = {0.0};
      o.ambient_irradiance = 5.0;
    }
    if (variant.find("vehicle") != std::string::npos) o.motion = sim::MotionKind::Vehicle;
  });
}

}  // namespace
}  // namespace nirslam
