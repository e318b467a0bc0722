#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string_view>

#include <Eigen/SVD>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "nirslam/sources/euroc_reader.hpp"  // seconds_from_nanoseconds

namespace nirslam {

namespace fs = std::filesystem;

namespace {

// The data lines of a trajectory file, trimmed: blank lines and '#' comments are skipped, and an
// EuRoC ground-truth header comment is noted (it tells EuRoC CSV from other comma files).
class DataLines {
public:
  explicit DataLines(std::istream& in) : in_(in) {}
  std::optional<std::string_view> next() {
    while (std::getline(in_, text_)) {
      ++number_;
      const std::string_view line = trim(text_);
      if (line.empty()) continue;
      if (line.front() != '#') return line;
      if (line.find("p_RS_R_x") != std::string_view::npos) euroc_header_ = true;
    }
    return std::nullopt;
  }
  int number() const { return number_; }  // of the line last returned, from 1
  bool euroc_header() const { return euroc_header_; }

private:
  std::istream& in_;
  std::string text_;
  int number_ = 0;
  bool euroc_header_ = false;
};

struct FormatSpec {
  TrajectoryFormat format;
  std::size_t min_fields;
  std::size_t max_fields;
  std::vector<std::string> columns;
  const char* layout;
};

const FormatSpec& spec_of(TrajectoryFormat format) {
  static const FormatSpec tum{TrajectoryFormat::Tum, 8, 8,
                              {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"},
                              "TUM 'timestamp tx ty tz qx qy qz qw'"};
  static const FormatSpec kitti{TrajectoryFormat::Kitti, 12, 12,
                                {"r11", "r12", "r13", "tx", "r21", "r22", "r23", "ty", "r31", "r32", "r33", "tz"},
                                "KITTI 'r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz'"};
  static const FormatSpec euroc{TrajectoryFormat::EurocCsv, 8, 64,
                                {"timestamp_ns", "p_x", "p_y", "p_z", "q_w", "q_x", "q_y", "q_z"},
                                "EuRoC CSV 'timestamp_ns, px, py, pz, qw, qx, qy, qz[, ...]'"};
  static const FormatSpec total_station{TrajectoryFormat::TotalStation, 4, 4, {"timestamp", "x", "y", "z"},
                                        "total station 'timestamp x y z'"};
  switch (format) {
    case TrajectoryFormat::Tum: return tum;
    case TrajectoryFormat::Kitti: return kitti;
    case TrajectoryFormat::EurocCsv: return euroc;
    case TrajectoryFormat::TotalStation: return total_station;
    case TrajectoryFormat::Auto: break;
  }
  throw std::logic_error("spec_of(Auto)");
}

std::string column_name(const FormatSpec& spec, std::size_t index) {
  return "column " + std::to_string(index + 1) +
         (index < spec.columns.size() ? " (" + spec.columns[index] + ")" : std::string());
}

double parse_number(std::string_view text, const fs::path& file, int line, const std::string& column) {
  if (text.empty()) throw InputError(file, line, column + " is empty");
  std::string_view digits = text;
  if (digits.front() == '+') digits.remove_prefix(1);
  double value = 0.0;
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (error == std::errc::result_out_of_range)
    throw InputError(file, line, column + " '" + std::string(text) + "' is out of range");
  if (error != std::errc() || end != digits.data() + digits.size())
    throw InputError(file, line, column + " '" + std::string(text) + "' is not a number");
  if (!std::isfinite(value))
    throw InputError(file, line, column + " is '" + std::string(text) + "': NaN and infinity are not accepted");
  return value;
}

std::int64_t parse_nanoseconds(std::string_view text, const fs::path& file, int line) {
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size()) {
    // Name NaN and friends as such; anything else is not an integer.
    double as_double = 0.0;
    const auto [end_d, error_d] = std::from_chars(text.data(), text.data() + text.size(), as_double);
    if (error_d == std::errc() && end_d == text.data() + text.size() && !std::isfinite(as_double))
      throw InputError(file, line, "column 1 (timestamp_ns) is '" + std::string(text) +
                                       "': NaN and infinity are not accepted");
    throw InputError(file, line, "column 1 (timestamp_ns) '" + std::string(text) +
                                     "' is not an integer number of nanoseconds");
  }
  if (value < 0) throw InputError(file, line, "column 1 (timestamp_ns) is negative");
  return value;
}

std::optional<TrajectoryFormat> format_of_fields(const std::vector<std::string_view>& fields, bool has_comma,
                                                 bool euroc_header) {
  if (has_comma && (fields.size() >= 8 || euroc_header)) return TrajectoryFormat::EurocCsv;
  switch (fields.size()) {
    case 8: return TrajectoryFormat::Tum;
    case 12: return TrajectoryFormat::Kitti;
    case 4: return TrajectoryFormat::TotalStation;
    default: return std::nullopt;
  }
}

std::string format_time(double t) {
  std::array<char, 64> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.6f", t);
  return buffer.data();
}

// Checks a new timestamp against the previous one and remembers it.
struct StampOrder {
  double previous = 0.0;
  int previous_line = 0;
  bool any = false;

  void check(double t, const fs::path& file, int line) {
    if (any && t == previous)
      throw InputError(file, line, "duplicate timestamp " + format_time(t) + " (also on line " +
                                       std::to_string(previous_line) + ")");
    if (any && t < previous)
      throw InputError(file, line, "timestamp " + format_time(t) + " is before line " + std::to_string(previous_line) +
                                       "'s " + format_time(previous) + ": timestamps must be sorted, increasing");
    previous = t;
    previous_line = line;
    any = true;
  }
};

Eigen::Quaterniond checked_quaternion(double w, double x, double y, double z, const fs::path& file, int line) {
  const Eigen::Quaterniond q(w, x, y, z);
  const double norm = q.norm();
  if (norm < 1e-9) throw InputError(file, line, "the quaternion is zero");
  if (std::abs(norm - 1.0) > 0.1)
    throw InputError(file, line, "the quaternion's norm is " + std::to_string(norm) +
                                     ", not 1 (wrong column order or not a quaternion)");
  return q.normalized();
}

Eigen::Matrix3d checked_rotation(const Eigen::Matrix3d& R, const fs::path& file, int line) {
  const double orthogonality = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
  if (orthogonality > 1e-2 || R.determinant() < 0.0)
    throw InputError(file, line, "the 3x3 part is not a rotation (|R^T R - I| = " + std::to_string(orthogonality) +
                                     ", det = " + std::to_string(R.determinant()) + ")");
  // Nearest rotation (polar decomposition), so that 6-digit files give an exact rotation.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

// Timestamps from a KITTI times.txt (one number a line) or a TUM monoVO times.txt (id t [exposure]).
std::vector<double> read_times_file(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, fs::exists(file) ? "cannot open" : "does not exist");
  std::vector<double> times;
  StampOrder order;
  int number = 0;
  for (std::string text; std::getline(in, text);) {
    ++number;
    const std::string_view line = trim(text);
    if (line.empty() || line.front() == '#') continue;
    const auto fields = split_fields(line);
    if (fields.size() > 3)
      throw InputError(file, number, "expected one timestamp in seconds, or 'id timestamp_s [exposure_ms]'; found " +
                                         std::to_string(fields.size()) + " fields");
    const std::size_t column = fields.size() == 1 ? 0 : 1;
    const double t = parse_number(fields[column], file, number, "column " + std::to_string(column + 1) + " (timestamp)");
    order.check(t, file, number);
    times.push_back(t);
  }
  if (in.bad()) throw InputError(file, "read error");
  return times;
}

}  // namespace

std::string to_string(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::Auto: return "auto";
    case TrajectoryFormat::Tum: return "tum";
    case TrajectoryFormat::Kitti: return "kitti";
    case TrajectoryFormat::EurocCsv: return "euroc";
    case TrajectoryFormat::TotalStation: return "total-station";
  }
  return "unknown";
}

std::optional<TrajectoryFormat> trajectory_format_from_string(const std::string& name) {
  for (const TrajectoryFormat f : {TrajectoryFormat::Auto, TrajectoryFormat::Tum, TrajectoryFormat::Kitti,
                                   TrajectoryFormat::EurocCsv, TrajectoryFormat::TotalStation})
    if (name == to_string(f)) return f;
  return std::nullopt;
}

std::vector<Eigen::Vector3d> Trajectory::positions() const {
  std::vector<Eigen::Vector3d> result;
  result.reserve(poses.size());
  for (const TimedPose& p : poses) result.push_back(p.T_world_cam.translation());
  return result;
}

std::vector<double> Trajectory::timestamps() const {
  std::vector<double> result;
  result.reserve(poses.size());
  for (const TimedPose& p : poses) result.push_back(p.timestamp_s);
  return result;
}

Trajectory parse_trajectory(std::istream& in, const fs::path& file, const TrajectoryReadOptions& options) {
  Trajectory trajectory;
  trajectory.source = file;
  TrajectoryFormat format = options.format;
  int detected_on = 0;
  StampOrder order;
  DataLines lines(in);
  while (const auto line = lines.next()) {
    const int number = lines.number();
    const auto fields = split_fields(*line);
    const bool has_comma = line->find(',') != std::string_view::npos;
    if (format == TrajectoryFormat::Auto) {
      const auto detected = format_of_fields(fields, has_comma, lines.euroc_header());
      if (!detected)
        throw InputError(file, number, "cannot tell the trajectory format from " + std::to_string(fields.size()) +
                                           " fields: expected TUM (8 numbers), KITTI (12), total station "
                                           "'timestamp x y z' (4) or EuRoC CSV (comma-separated, 8 or more)");
      format = *detected;
      detected_on = number;
    }
    const FormatSpec& spec = spec_of(format);
    if (fields.size() < spec.min_fields || fields.size() > spec.max_fields) {
      const std::string expected = spec.min_fields == spec.max_fields
                                       ? std::to_string(spec.min_fields)
                                       : std::to_string(spec.min_fields) + " or more";
      throw InputError(file, number,
                       "expected " + expected + " fields of " + spec.layout +
                           (detected_on > 0 ? " (format detected on line " + std::to_string(detected_on) + ")" : "") +
                           ", found " + std::to_string(fields.size()));
    }

    std::array<double, 12> v{};
    const std::size_t numeric_from = format == TrajectoryFormat::EurocCsv ? 1 : 0;
    const std::size_t used = spec.columns.size();
    for (std::size_t i = numeric_from; i < used; ++i) v[i] = parse_number(fields[i], file, number, column_name(spec, i));
    // EuRoC's further columns (velocity, biases) are not used but must still be numbers.
    for (std::size_t i = used; i < fields.size(); ++i) parse_number(fields[i], file, number, column_name(spec, i));

    TimedPose pose;
    switch (format) {
      case TrajectoryFormat::Tum:
        pose.timestamp_s = v[0];
        pose.T_world_cam = SE3(checked_quaternion(v[7], v[4], v[5], v[6], file, number), Eigen::Vector3d(v[1], v[2], v[3]));
        break;
      case TrajectoryFormat::Kitti: {
        Eigen::Matrix3d R;
        R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
        pose.timestamp_s = static_cast<double>(trajectory.poses.size());  // replaced below
        pose.T_world_cam = SE3(Eigen::Matrix3d(checked_rotation(R, file, number)), Eigen::Vector3d(v[3], v[7], v[11]));
        break;
      }
      case TrajectoryFormat::EurocCsv:
        pose.timestamp_s = seconds_from_nanoseconds(parse_nanoseconds(fields[0], file, number));
        pose.T_world_cam = SE3(checked_quaternion(v[4], v[5], v[6], v[7], file, number), Eigen::Vector3d(v[1], v[2], v[3]));
        break;
      case TrajectoryFormat::TotalStation:
        pose.timestamp_s = v[0];
        pose.T_world_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(v[1], v[2], v[3]));
        break;
      case TrajectoryFormat::Auto: break;
    }
    if (format != TrajectoryFormat::Kitti) order.check(pose.timestamp_s, file, number);
    trajectory.poses.push_back(pose);
  }
  if (in.bad()) throw InputError(file, "read error");
  if (trajectory.poses.empty()) throw InputError(file, "holds no poses (only blank or '#' comment lines)");
  trajectory.format = format;
  trajectory.position_only = format == TrajectoryFormat::TotalStation;

  if (format == TrajectoryFormat::Kitti) {
    if (options.kitti.times_file) {
      const std::vector<double> times = read_times_file(*options.kitti.times_file);
      if (times.size() != trajectory.poses.size())
        throw InputError(*options.kitti.times_file, "lists " + std::to_string(times.size()) + " timestamps but " +
                                                         file.string() + " holds " +
                                                         std::to_string(trajectory.poses.size()) + " poses");
      for (std::size_t k = 0; k < times.size(); ++k) trajectory.poses[k].timestamp_s = times[k];
    } else if (options.kitti.rate_hz) {
      const double rate = *options.kitti.rate_hz;
      if (!(rate > 0.0) || !std::isfinite(rate))
        throw InputError(file, "KITTI rate must be a positive number of Hz, not " + std::to_string(rate));
      for (std::size_t k = 0; k < trajectory.poses.size(); ++k)
        trajectory.poses[k].timestamp_s = static_cast<double>(k) / rate;
    }
  }
  return trajectory;
}

Trajectory read_trajectory(const fs::path& file, const TrajectoryReadOptions& options) {
  if (!fs::exists(file)) throw InputError(file, "does not exist");
  if (fs::is_directory(file)) throw InputError(file, "is a folder, not a trajectory file");
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open");
  return parse_trajectory(in, file, options);
}

Trajectory read_trajectory(const fs::path& file, TrajectoryFormat format) {
  TrajectoryReadOptions options;
  options.format = format;
  return read_trajectory(file, options);
}

TrajectoryFormat detect_trajectory_format(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, fs::exists(file) ? "cannot open" : "does not exist");
  DataLines lines(in);
  if (const auto line = lines.next()) {
    const auto fields = split_fields(*line);
    if (const auto format = format_of_fields(fields, line->find(',') != std::string_view::npos, lines.euroc_header()))
      return *format;
    throw InputError(file, lines.number(),
                     "cannot tell the trajectory format from " + std::to_string(fields.size()) + " fields");
  }
  throw InputError(file, "holds no poses (only blank or '#' comment lines)");
}

namespace {

void write_lines(const fs::path& file, const Trajectory& trajectory, bool with_rotation) {
  std::ofstream out(file);
  if (!out) throw InputError(file, "cannot open for writing");
  out << (with_rotation ? "# timestamp_s tx ty tz qx qy qz qw (T_world_cam)\n" : "# timestamp_s x y z\n");
  std::array<char, 256> buffer{};
  for (const TimedPose& p : trajectory.poses) {
    const Eigen::Vector3d& t = p.T_world_cam.translation();
    const Eigen::Quaterniond& q = p.T_world_cam.unit_quaternion();
    const int n = with_rotation
                      ? std::snprintf(buffer.data(), buffer.size(), "%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                                      p.timestamp_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w())
                      : std::snprintf(buffer.data(), buffer.size(), "%.9f %.9f %.9f %.9f\n", p.timestamp_s, t.x(),
                                      t.y(), t.z());
    if (n < 0 || static_cast<std::size_t>(n) >= buffer.size())
      throw InputError(file, "a pose does not fit a line (non-finite or huge numbers)");
    out.write(buffer.data(), n);
  }
  out.flush();
  if (!out) throw InputError(file, "write failed (disk full?)");
}

}  // namespace

void write_tum(const fs::path& file, const Trajectory& trajectory) {
  if (trajectory.position_only)
    throw std::invalid_argument("write_tum: " + trajectory.source.string() +
                                " is position-only; TUM needs orientations (use write_positions)");
  write_lines(file, trajectory, true);
}

void write_positions(const fs::path& file, const Trajectory& trajectory) { write_lines(file, trajectory, false); }

void validate_trajectory(const Trajectory& trajectory, const std::string& name) {
  const fs::path source = trajectory.source.empty() ? fs::path(name) : trajectory.source;
  if (trajectory.poses.empty()) throw InputError(source, "holds no poses");
  for (std::size_t k = 0; k < trajectory.poses.size(); ++k) {
    const TimedPose& p = trajectory.poses[k];
    const std::string field = "pose " + std::to_string(k);
    if (!std::isfinite(p.timestamp_s)) throw InputError(source, field, "timestamp is NaN or infinite");
    if (!p.T_world_cam.translation().allFinite() || !p.T_world_cam.unit_quaternion().coeffs().allFinite())
      throw InputError(source, field, "pose holds NaN or infinite numbers");
    if (k > 0) {
      const double previous = trajectory.poses[k - 1].timestamp_s;
      if (p.timestamp_s == previous)
        throw InputError(source, field, "duplicate timestamp " + format_time(p.timestamp_s) + " (also pose " +
                                            std::to_string(k - 1) + ")");
      if (p.timestamp_s < previous)
        throw InputError(source, field, "timestamp " + format_time(p.timestamp_s) + " is before pose " +
                                            std::to_string(k - 1) + "'s " + format_time(previous) +
                                            ": timestamps must be sorted, increasing");
    }
  }
}

Trajectory transform_body_to_camera(const Trajectory& body, const SE3& T_body_cam) {
  if (body.position_only)
    throw std::invalid_argument(body.source.string() + " is position-only: a body-to-camera transform needs orientations");
  Trajectory camera = body;
  for (TimedPose& p : camera.poses) p.T_world_cam = p.T_world_cam * T_body_cam;
  return camera;
}

}  // namespace nirslam
