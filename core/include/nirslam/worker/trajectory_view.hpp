#pragma once
// What the UI's 3-D view and the headless writers see of the odometry: every frame's pose, the
// keyframes, the map points, the ground truth when the source has it, and the tracking state.
// Float positions: the view draws them, the trajectory files are written from the odometry's
// own double-precision poses.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace nirslam {

struct PoseSample {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  int segment = 0;                       // increments after every tracking loss
  Eigen::Vector3f position = Eigen::Vector3f::Zero();   // camera centre in the world
  Eigen::Quaternionf rotation = Eigen::Quaternionf::Identity();  // R_world_cam
  float error_m = -1.0f;                 // distance to the aligned ground truth, -1 when unknown
};

struct MapPointSample {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  float intensity = 0.0f;                // 0..255
  bool active = true;                    // in the window; false = marginalised
};

struct TrajectoryView {
  bool enabled = false;                  // the pipeline mode runs the odometry at all
  std::string tracking;                  // "initialising", "tracking", "lost", "new segment"
  std::string message;                   // why, when tracking is in trouble
  int segment = 0;
  std::vector<PoseSample> poses;         // every frame with a pose, oldest first
  std::vector<PoseSample> keyframes;     // in the window and marginalised
  // Replaced on keyframes only (it can hold 100k points): shared between views until then.
  std::shared_ptr<const std::vector<MapPointSample>> points;
  std::optional<PoseSample> current;     // the latest frame's pose
  // The window's active points seen from the latest frame: pixel in the source's (raw) image and
  // depth along the optical axis (in the estimate's units), for the feed's overlay.
  std::vector<Eigen::Vector2f> current_pixels;
  std::vector<float> current_depths;
  // Ground truth as the source reports it (simulator). When enough poses of the current segment
  // have it, the estimate (poses, keyframes, points) is given aligned to it by Sim(3) (Umeyama),
  // so the view draws both in metres and error_m is the absolute trajectory error per pose.
  std::vector<Eigen::Vector3f> ground_truth;
  bool aligned_to_ground_truth = false;
  std::optional<double> ate_rmse_m;      // of the aligned current segment
  double path_length = 0.0;              // of the estimate, in its (displayed) units
};

}  // namespace nirslam
