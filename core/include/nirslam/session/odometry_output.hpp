#pragma once
// What a run writes about the odometry (DESIGN.md, "Formats"):
//   trajectory.txt  every frame with a pose, TUM format (timestamp tx ty tz qx qy qz qw, camera to
//                   world, the source's timestamps); segments after a tracking loss follow each
//                   other in the same file, each after a comment line "# segment N" (TUM
//                   readers skip comments; read_trajectory_segments() splits them)
//   keyframes.txt   "# frame_index timestamp segment marginalised affine_a affine_b" then the TUM pose
//   points.ply      the map points (active and marginalised), binary little-endian PLY with
//                   x y z (float), intensity (uchar) and active (uchar)
// Each throws std::runtime_error naming the file when it cannot be written (full disk).

#include <filesystem>
#include <vector>

#include "nirslam/eval/trajectory.hpp"
#include "nirslam/odometry/direct_odometry.hpp"

namespace nirslam {

void write_trajectory_tum(const std::filesystem::path& file, const std::vector<PoseStamped>& trajectory);
void write_keyframes(const std::filesystem::path& file, const std::vector<KeyframeState>& keyframes);
void write_points_ply(const std::filesystem::path& file, const std::vector<MapPoint>& points);

// trajectory.txt split at its "# segment N" lines (one trajectory when there are none). Throws
// InputError naming the file and line for malformed pose lines.
std::vector<Trajectory> read_trajectory_segments(const std::filesystem::path& file);

}  // namespace nirslam
