#pragma once

// Trajectories as value types, and the readers and writer of the formats that ground truth and
// estimates come in. Poses are T_world_cam (camera to world), as in the TUM format.
//
//   TUM            timestamp_s tx ty tz qx qy qz qw                      (8 numbers, blank-separated)
//   KITTI          r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz           (12 numbers, no timestamp)
//   EuRoC CSV      timestamp_ns, px, py, pz, qw, qx, qy, qz [, ...]       (ground truth data.csv;
//                  quaternion order w, x, y, z; further columns such as velocities are ignored)
//   total station  timestamp_s x y z                                     (positions only, e.g. a
//                  Leica TS60 log; blanks or commas)
//
// Lines starting with '#' and blank lines are skipped everywhere. Every malformed line, every
// NaN or infinite number, and every timestamp that is not strictly after the previous one throws
// InputError naming the file and the line. Nothing is reordered or dropped silently.

#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"

namespace nirslam {

struct TimedPose {
  double timestamp_s = 0.0;
  SE3 T_world_cam;
};

enum class TrajectoryFormat { Auto, Tum, Kitti, EurocCsv, TotalStation };

// "auto", "tum", "kitti", "euroc", "total-station" (the names the command line accepts).
std::string to_string(TrajectoryFormat format);
// Inverse of to_string; std::nullopt for an unknown name.
std::optional<TrajectoryFormat> trajectory_format_from_string(const std::string& name);

struct Trajectory {
  std::vector<TimedPose> poses;  // strictly increasing timestamps
  // True for position-only sources (total-station logs): the rotations are identity and carry no
  // information; only translation-based measures apply and alignment uses positions.
  bool position_only = false;
  // Where the poses came from: names the trajectory in errors. Empty for one built in memory.
  std::filesystem::path source;
  TrajectoryFormat format = TrajectoryFormat::Auto;  // the format read (Auto: built in memory)

  std::size_t size() const { return poses.size(); }
  bool empty() const { return poses.empty(); }
  std::vector<Eigen::Vector3d> positions() const;
  std::vector<double> timestamps() const;
};

// KITTI files have no timestamps. They come from `times_file` (one timestamp in seconds per line,
// KITTI's times.txt; or TUM monoVO's "id timestamp_s [exposure_ms]", whose second column is used),
// else from `rate_hz` (pose k at k / rate_hz), else the frame index is the timestamp in seconds
// (pose k at k s), which pairs two KITTI files pose by pose.
struct KittiTiming {
  std::optional<std::filesystem::path> times_file;
  std::optional<double> rate_hz;
};

struct TrajectoryReadOptions {
  TrajectoryFormat format = TrajectoryFormat::Auto;
  KittiTiming kitti;
};

// Auto-detection looks at the first data line: commas and at least 8 fields (or a comment naming
// p_RS_R_x) mean EuRoC CSV; otherwise 8 numbers TUM, 12 KITTI, 4 total station.
Trajectory read_trajectory(const std::filesystem::path& file, const TrajectoryReadOptions& options = {});
Trajectory read_trajectory(const std::filesystem::path& file, TrajectoryFormat format);
// The same from a stream; `file` only names the source in errors (and resolves nothing).
Trajectory parse_trajectory(std::istream& in, const std::filesystem::path& file,
                            const TrajectoryReadOptions& options = {});

// The format of the first data line of `file` (throws InputError when it fits none).
TrajectoryFormat detect_trajectory_format(const std::filesystem::path& file);

// Writes "timestamp_s tx ty tz qx qy qz qw" lines under a '#' header, 9 decimals. Throws
// std::invalid_argument for a position-only trajectory (TUM needs orientations: use
// write_positions) and InputError when the file cannot be written.
void write_tum(const std::filesystem::path& file, const Trajectory& trajectory);
// Writes "timestamp_s x y z" lines (the total-station form).
void write_positions(const std::filesystem::path& file, const Trajectory& trajectory);

// Checks what the readers check, for a trajectory built in memory (a simulator, an odometry run):
// at least one pose, finite numbers, strictly increasing timestamps. Throws InputError naming
// trajectory.source (or `name` when it is empty) and the pose index as the field.
void validate_trajectory(const Trajectory& trajectory, const std::string& name = "trajectory");

// Every pose right-multiplied by T_body_cam: body (IMU) poses to camera poses, e.g. EuRoC ground
// truth times sensor.yaml's T_BS. Position-only trajectories are rejected (std::invalid_argument):
// without an orientation the lever arm cannot be applied.
Trajectory transform_body_to_camera(const Trajectory& body, const SE3& T_body_cam);

}  // namespace nirslam
