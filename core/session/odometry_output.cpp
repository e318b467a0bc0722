#include "nirslam/session/odometry_output.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <stdexcept>

#include <fmt/format.h>

#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

std::ofstream open_for_writing(const std::filesystem::path& file, std::ios::openmode mode = std::ios::out) {
  std::ofstream out(file, mode | std::ios::trunc);
  if (!out) throw std::runtime_error(file.string() + ": cannot open for writing");
  return out;
}

void finish(std::ofstream& out, const std::filesystem::path& file) {
  out.flush();
  if (!out) throw std::runtime_error(file.string() + ": write failed (disk full?)");
}

std::string tum_pose(const SE3& T) {
  const Eigen::Vector3d& t = T.translation();
  const Eigen::Quaterniond& q = T.unit_quaternion();
  return fmt::format("{:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f}", t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
}

}  // namespace

void write_trajectory_tum(const std::filesystem::path& file, const std::vector<PoseStamped>& trajectory) {
  std::ofstream out = open_for_writing(file);
  out << "# timestamp tx ty tz qx qy qz qw (camera to world; nirslam odometry)\n";
  int segment = -1;
  for (const PoseStamped& p : trajectory) {
    // A new segment after a tracking loss has its own scale and origin: say where it starts.
    if (p.segment != segment) out << "# segment " << p.segment << '\n';
    segment = p.segment;
    out << fmt::format("{:.9f} {}\n", p.timestamp_s, tum_pose(p.T_world_cam));
  }
  finish(out, file);
}

void write_keyframes(const std::filesystem::path& file, const std::vector<KeyframeState>& keyframes) {
  std::ofstream out = open_for_writing(file);
  out << "# frame_index timestamp segment marginalised affine_a affine_b tx ty tz qx qy qz qw\n";
  for (const KeyframeState& k : keyframes)
    out << fmt::format("{} {:.9f} {} {} {:.6f} {:.6f} {}\n", k.frame_index, k.timestamp_s, k.segment, k.marginalised ? 1 : 0,
                       k.affine_a, k.affine_b, tum_pose(k.T_world_cam));
  finish(out, file);
}

void write_points_ply(const std::filesystem::path& file, const std::vector<MapPoint>& points) {
  std::ofstream out = open_for_writing(file, std::ios::out | std::ios::binary);
  out << "ply\nformat binary_little_endian 1.0\ncomment nirslam map points\n"
      << "element vertex " << points.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar intensity\nproperty uchar active\nend_header\n";
  static_assert(std::endian::native == std::endian::little, "PLY writer assumes a little-endian host");
  for (const MapPoint& p : points) {
    const float xyz[3] = {static_cast<float>(p.p_world.x()), static_cast<float>(p.p_world.y()),
                          static_cast<float>(p.p_world.z())};
    const std::uint8_t extra[2] = {static_cast<std::uint8_t>(std::clamp(p.intensity, 0.0f, 255.0f)),
                                   static_cast<std::uint8_t>(p.active ? 1 : 0)};
    out.write(reinterpret_cast<const char*>(xyz), sizeof(xyz));
    out.write(reinterpret_cast<const char*>(extra), sizeof(extra));
  }
  finish(out, file);
}

}  // namespace nirslam

namespace nirslam {

std::vector<Trajectory> read_trajectory_segments(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open the trajectory");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(std::move(line));
  // Chunks between "# segment" markers; lines of other chunks are blanked so errors keep the
  // file's own line numbers.
  std::vector<std::size_t> starts{0};
  for (std::size_t i = 0; i < lines.size(); ++i)
    if (lines[i].rfind("# segment", 0) == 0 && i > 0) starts.push_back(i);
  starts.push_back(lines.size());
  std::vector<Trajectory> segments;
  TrajectoryReadOptions options;
  options.format = TrajectoryFormat::Tum;
  for (std::size_t s = 0; s + 1 < starts.size(); ++s) {
    std::string text;
    bool has_data = false;
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const bool inside = i >= starts[s] && i < starts[s + 1];
      if (inside && !lines[i].empty() && lines[i][0] != '#') has_data = true;
      text += inside ? lines[i] : std::string();
      text += '\n';
    }
    if (!has_data) continue;
    std::istringstream chunk(text);
    Trajectory t = parse_trajectory(chunk, file, options);
    t.source = file;
    segments.push_back(std::move(t));
  }
  return segments;
}

}  // namespace nirslam
