#pragma once

// Smooth camera paths through the simulator's scenes.
//
// Position: a closed loop per scene (an ellipse round the room's table, a rounded rectangle round
// the street block, a stadium round the parking's central pillar row, a stadium up one side of
// the tunnel and back the other), resampled every 0.5 m and used as the control polygon of a
// periodic uniform quintic B-spline (C4), run through at a constant parameter rate, so the speed
// is nearly constant. Orientation: the heading of the velocity plus, per kind of motion, sums of
// sinusoids (look-around, bob, sway, tremor, vibration), all smooth. Every path keeps clear of
// the scene's geometry (checked by the tests).

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/sim/scene.hpp"

namespace nirslam::sim {

enum class MotionKind {
  Handheld,  // walking speed, camera at eye height, looking around, bob and tremor
  Vehicle,   // a cart or car: faster, heading follows the path, slight vibration
  Robot,     // a small ground robot: slow, low camera, tilted up a little
  Tripod,    // the rig stands still (where the handheld path starts): power and exposure sweeps
};

std::string_view to_string(MotionKind kind);
// "handheld" (also "hand-held"), "vehicle", "robot", "tripod" (also "still"); any case.
std::optional<MotionKind> parse_motion_kind(std::string_view name);

class Trajectory {
public:
  Trajectory(std::vector<Eigen::Vector2d> control_points, double height, double speed_mps, MotionKind kind,
             std::uint32_t seed);

  // T_world_cam at time t (s); the position repeats every period().
  SE3 pose(double t) const;
  Eigen::Vector3d position(double t) const;
  double period() const { return period_; }          // one loop, s
  double loop_length() const { return length_; }      // m
  double speed() const { return speed_; }             // m/s
  MotionKind kind() const { return kind_; }

private:
  Eigen::Vector2d spline(double u) const;  // the loop at spline parameter u (control-point units)

  std::vector<Eigen::Vector2d> control_;
  double height_;
  double speed_;
  MotionKind kind_;
  double length_ = 0.0;
  double period_ = 0.0;
  Eigen::Matrix<double, 8, 1> phase_;  // phases of the sinusoids, from the seed
};

// The trajectory of a kind of motion through a scene.
Trajectory make_trajectory(SceneKind scene, MotionKind kind, std::uint32_t seed);

// The paper's capture rule: a new frame when max_interval_s has passed or the camera has moved
// max_distance_m since the last frame, whichever comes first.
struct CaptureRule {
  double max_interval_s = 0.1;
  double max_distance_m = 0.002;
};

// Times of `count` frames from t = 0: every 1/fps, or by the capture rule when given.
std::vector<double> frame_times(const Trajectory& trajectory, std::int64_t count, double fps,
                                const std::optional<CaptureRule>& rule = std::nullopt);

}  // namespace nirslam::sim
