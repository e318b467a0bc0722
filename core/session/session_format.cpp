#include "nirslam/session/session_format.hpp"

#include <fcntl.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <ctime>
#include <fstream>
#include <sstream>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
namespace fs = std::filesystem;
namespace {

[[noreturn]] void throw_errno(int code, const fs::path& file, const std::string& what) {
  throw std::system_error(code, std::generic_category(), file.string() + ": " + what);
}

// Closes on scope exit; the writer checks close() itself where it matters.
struct FileDescriptor {
  int fd = -1;
  ~FileDescriptor() {
    if (fd >= 0) ::close(fd);
  }
};

void fsync_folder(const fs::path& folder) {
  FileDescriptor dir{::open(folder.empty() ? "." : folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (dir.fd < 0) throw_errno(errno, folder, "cannot open the folder to sync it");
  if (::fsync(dir.fd) != 0) throw_errno(errno, folder, "cannot sync the folder");
}

std::string journal_number_or_blank(const std::optional<double>& value) {
  return value ? fmt::format("{:.9g}", *value) : std::string();
}

std::vector<std::string_view> split_commas(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (comma == std::string_view::npos) return fields;
    start = comma + 1;
  }
}

constexpr std::size_t kJournalColumns = 24;
constexpr const char* kColumnNames[kJournalColumns] = {
    "position", "source_index", "timestamp_s", "exposure_ms", "gain", "illuminator_power_w", "entropy_bits",
    "bit_depth", "file", "bytes", "tx", "ty", "tz", "qx", "qy", "qz", "qw",
    "gt_tx", "gt_ty", "gt_tz", "gt_qx", "gt_qy", "gt_qz", "gt_qw"};

double parse_double(std::string_view text, const fs::path& file, int line, std::size_t column) {
  double value = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(value))
    throw InputError(file, line, fmt::format("{}: expected a finite number, got '{}'", kColumnNames[column], text));
  return value;
}

std::int64_t parse_integer(std::string_view text, const fs::path& file, int line, std::size_t column) {
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value < 0)
    throw InputError(file, line, fmt::format("{}: expected a non-negative integer, got '{}'", kColumnNames[column], text));
  return value;
}

std::optional<double> parse_optional(std::string_view text, const fs::path& file, int line, std::size_t column) {
  if (text.empty()) return std::nullopt;
  return parse_double(text, file, line, column);
}

// Seven fields from `first`: tx ty tz qx qy qz qw, all empty (no pose) or all numbers.
std::optional<SE3> parse_pose(const std::vector<std::string_view>& fields, std::size_t first, const fs::path& file,
                              int line) {
  bool any = false, all = true;
  for (std::size_t i = first; i < first + 7; ++i) {
    any = any || !fields[i].empty();
    all = all && !fields[i].empty();
  }
  if (!any) return std::nullopt;
  if (!all) throw InputError(file, line, fmt::format("{}..{}: a pose needs all seven numbers", kColumnNames[first], kColumnNames[first + 6]));
  double v[7];
  for (std::size_t i = 0; i < 7; ++i) v[i] = parse_double(fields[first + i], file, line, first + i);
  Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (std::abs(q.norm() - 1.0) > 1e-3)
    throw InputError(file, line, fmt::format("{}..{}: the quaternion is not of unit length", kColumnNames[first + 3], kColumnNames[first + 6]));
  return SE3(q.normalized(), Eigen::Vector3d(v[0], v[1], v[2]));
}

std::string format_pose(const std::optional<SE3>& pose) {
  if (!pose) return ",,,,,,";
  const Eigen::Vector3d& t = pose->translation();
  const Eigen::Quaterniond& q = pose->unit_quaternion();
  return fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}", t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
}

}  // namespace

const char* to_string(SessionState state) {
  switch (state) {
    case SessionState::Recording: return "recording";
    case SessionState::Complete: return "complete";
    case SessionState::Recovered: return "recovered";
  }
  return "unknown";
}

std::optional<SessionState> parse_session_state(std::string_view text) {
  for (SessionState s : {SessionState::Recording, SessionState::Complete, SessionState::Recovered})
    if (text == to_string(s)) return s;
  return std::nullopt;
}

const char* to_string(FrameFileFormat format) { return format == FrameFileFormat::Png ? "png" : "pgm"; }
const char* file_extension(FrameFileFormat format) { return format == FrameFileFormat::Png ? ".png" : ".pgm"; }
std::optional<FrameFileFormat> parse_frame_file_format(std::string_view text) {
  if (text == "png") return FrameFileFormat::Png;
  if (text == "pgm") return FrameFileFormat::Pgm;
  return std::nullopt;
}

nlohmann::json to_json(const SessionMetadata& m) {
  return {
      {"format_version", 1},
      {"state", to_string(m.state)},
      {"nirslam_version", m.nirslam_version},
      {"started_utc", m.started_utc},
      {"stopped_utc", m.stopped_utc},
      {"recovered_utc", m.recovered_utc},
      {"notes", m.notes},
      {"source", {{"kind", m.source_kind}, {"description", m.source_description}, {"nominal_fps", m.nominal_fps}}},
      {"camera", m.camera},
      {"image", {{"width", m.width}, {"height", m.height}, {"bit_depth", m.bit_depth}, {"file_format", to_string(m.format)},
                 {"png_compression", m.png_compression}}},
      {"frames_written", m.frames_written},
      {"frames_dropped", m.frames_dropped},
      {"dropped_source_indices", m.dropped_indices},
      {"stop_reason", m.stop_reason},
      {"recovery_report", m.recovery_report},
      {"outputs", m.outputs},
  };
}

SessionMetadata metadata_from_json(const nlohmann::json& json, const fs::path& file) {
  SessionMetadata m;
  const auto field = [&](const nlohmann::json& parent, const char* name, const std::string& path) -> const nlohmann::json& {
    if (!parent.is_object() || !parent.contains(name)) throw InputError(file, path, "missing");
    return parent.at(name);
  };
  try {
    const std::string state = field(json, "state", "state").get<std::string>();
    const auto parsed = parse_session_state(state);
    if (!parsed) throw InputError(file, "state", "expected recording, complete or recovered, got '" + state + "'");
    m.state = *parsed;
    m.nirslam_version = field(json, "nirslam_version", "nirslam_version").get<std::string>();
    m.started_utc = json.value("started_utc", "");
    m.stopped_utc = json.value("stopped_utc", "");
    m.recovered_utc = json.value("recovered_utc", "");
    m.notes = json.value("notes", "");
    const auto& source = field(json, "source", "source");
    m.source_kind = source.value("kind", "");
    m.source_description = source.value("description", "");
    m.nominal_fps = source.value("nominal_fps", 0.0);
    m.camera = json.value("camera", "");
    const auto& image = field(json, "image", "image");
    m.width = field(image, "width", "image.width").get<int>();
    m.height = field(image, "height", "image.height").get<int>();
    m.bit_depth = field(image, "bit_depth", "image.bit_depth").get<int>();
    const std::string format = field(image, "file_format", "image.file_format").get<std::string>();
    const auto parsed_format = parse_frame_file_format(format);
    if (!parsed_format) throw InputError(file, "image.file_format", "expected png or pgm, got '" + format + "'");
    m.format = *parsed_format;
    m.png_compression = image.value("png_compression", 1);
    m.frames_written = field(json, "frames_written", "frames_written").get<std::int64_t>();
    m.frames_dropped = json.value("frames_dropped", std::int64_t{0});
    m.dropped_indices = json.value("dropped_source_indices", std::vector<std::int64_t>{});
    m.stop_reason = json.value("stop_reason", "");
    m.recovery_report = json.value("recovery_report", "");
    m.outputs = json.value("outputs", std::vector<std::string>{});
  } catch (const nlohmann::json::exception& e) {
    throw InputError(file, std::string("wrong type of a field: ") + e.what());
  }
  return m;
}

SessionMetadata read_session_metadata(const fs::path& session_folder) {
  const fs::path file = session_folder / session_files::kMetadata;
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open the session metadata (is this a recorded session?)");
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(file, std::string("not valid JSON: ") + e.what());
  }
  return metadata_from_json(json, file);
}

void write_session_metadata(const fs::path& session_folder, const SessionMetadata& metadata) {
  write_file_durably(session_folder / session_files::kMetadata, to_json(metadata).dump(2) + "\n");
}

std::string format_journal_line(const JournalEntry& e) {
  return fmt::format("{},{},{:.9f},{},{},{},{},{},{},{},{},{}\n", e.position, e.source_index, e.timestamp_s,
                     journal_number_or_blank(e.exposure_ms), journal_number_or_blank(e.gain), journal_number_or_blank(e.illuminator_power_w),
                     journal_number_or_blank(e.entropy_bits), e.bit_depth, e.file, e.bytes, format_pose(e.T_world_cam),
                     format_pose(e.T_world_cam_truth));
}

JournalEntry parse_journal_line(std::string_view line, const fs::path& file, int line_number) {
  const auto fields = split_commas(line);
  if (fields.size() != kJournalColumns)
    throw InputError(file, line_number, fmt::format("expected {} comma-separated fields, got {}", kJournalColumns, fields.size()));
  JournalEntry e;
  e.position = parse_integer(fields[0], file, line_number, 0);
  e.source_index = parse_integer(fields[1], file, line_number, 1);
  e.timestamp_s = parse_double(fields[2], file, line_number, 2);
  e.exposure_ms = parse_optional(fields[3], file, line_number, 3);
  e.gain = parse_optional(fields[4], file, line_number, 4);
  e.illuminator_power_w = parse_optional(fields[5], file, line_number, 5);
  e.entropy_bits = parse_optional(fields[6], file, line_number, 6);
  const std::int64_t depth = parse_integer(fields[7], file, line_number, 7);
  if (depth < 8 || depth > 16) throw InputError(file, line_number, fmt::format("bit_depth: expected 8..16, got {}", depth));
  e.bit_depth = static_cast<int>(depth);
  e.file = std::string(fields[8]);
  if (e.file.empty() || e.file.find("..") != std::string::npos || e.file.front() == '/')
    throw InputError(file, line_number, "file: expected a path inside the session, got '" + e.file + "'");
  e.bytes = static_cast<std::uint64_t>(parse_integer(fields[9], file, line_number, 9));
  e.T_world_cam = parse_pose(fields, 10, file, line_number);
  e.T_world_cam_truth = parse_pose(fields, 17, file, line_number);
  return e;
}

JournalContents read_journal(const fs::path& file, bool tolerate_damage) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, "cannot open the journal");
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  JournalContents contents;
  contents.file_bytes = text.size();
  std::size_t start = 0;
  int line_number = 0;
  while (start < text.size()) {
    ++line_number;
    const std::size_t end = text.find('\n', start);
    const auto damaged = [&](const std::string& why) {
      if (!tolerate_damage) throw InputError(file, line_number, why);
      contents.bad_line = line_number;
      contents.bad_line_error = why;
    };
    if (end == std::string::npos) {
      damaged("torn line: no line end (the recorder stopped while writing it)");
      break;
    }
    const std::string_view line(text.data() + start, end - start);
    if (line_number == 1) {
      if (line != kJournalHeader) {
        damaged("not a nirslam session journal header");
        break;
      }
    } else {
      try {
        contents.entries.push_back(parse_journal_line(line, file, line_number));
      } catch (const InputError& e) {
        if (!tolerate_damage) throw;
        contents.bad_line = line_number;
        contents.bad_line_error = e.what();
        break;
      }
    }
    start = end + 1;
    contents.intact_bytes = start;
  }
  return contents;
}

std::string frame_file_name(std::int64_t position, FrameFileFormat format) {
  return fmt::format("{}/{:06d}{}", session_files::kFrames, position, file_extension(format));
}

void write_file_durably(const fs::path& file, const void* bytes, std::size_t size) {
  const fs::path temp = fs::path(file.string() + session_files::kTempSuffix);
  FileDescriptor out{::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
  if (out.fd < 0) throw_errno(errno, file, "cannot create the file");
  const auto fail = [&](int code, const char* what) {
    ::close(out.fd);
    out.fd = -1;
    ::unlink(temp.c_str());
    throw_errno(code, file, what);
  };
  const char* data = static_cast<const char*>(bytes);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(out.fd, data + done, size - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail(errno, "cannot write");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(out.fd) != 0) fail(errno, "cannot sync to disk");
  const int fd = out.fd;
  out.fd = -1;
  if (::close(fd) != 0) {
    const int code = errno;
    ::unlink(temp.c_str());
    throw_errno(code, file, "cannot close");
  }
  if (::rename(temp.c_str(), file.c_str()) != 0) {
    const int code = errno;
    ::unlink(temp.c_str());
    throw_errno(code, file, "cannot rename the finished file into place");
  }
  fsync_folder(file.parent_path());
}

void write_file_durably(const fs::path& file, std::string_view text) { write_file_durably(file, text.data(), text.size()); }

std::uint64_t free_bytes(const fs::path& path) {
  struct statvfs stats {};
  if (::statvfs(path.c_str(), &stats) != 0) throw_errno(errno, path, "cannot read the free space");
  return static_cast<std::uint64_t>(stats.f_bavail) * static_cast<std::uint64_t>(stats.f_frsize);
}

std::string human_bytes(std::uint64_t bytes) {
  const double b = static_cast<double>(bytes);
  if (b >= 1024.0 * 1024.0 * 1024.0) return fmt::format("{:.1f} GiB", b / (1024.0 * 1024.0 * 1024.0));
  if (b >= 1024.0 * 1024.0) return fmt::format("{:.1f} MiB", b / (1024.0 * 1024.0));
  if (b >= 1024.0) return fmt::format("{:.0f} KiB", b / 1024.0);
  return fmt::format("{} B", bytes);
}

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

bool is_session_folder(const fs::path& folder) {
  std::error_code error;
  return fs::is_regular_file(folder / session_files::kMetadata, error);
}

void write_session_camera_file(const fs::path& file, const CameraModel& camera) {
  std::string first = fmt::format("{} {:.12g} {:.12g} {:.12g} {:.12g}", camera.name(), camera.fx(), camera.fy(),
                                  camera.cx(), camera.cy());
  const Eigen::VectorXd distortion = camera.distortion();
  if (distortion.size() == 0) first += " 0";
  for (Eigen::Index i = 0; i < distortion.size(); ++i) first += fmt::format(" {:.12g}", distortion[i]);
  // DSO leaves a pinhole as it is ("none") and rectifies a distorting lens to a cropped pinhole.
  const char* rectification = camera.type() == CameraModelType::Pinhole ? "none" : "crop";
  write_file_durably(file, fmt::format("{}\n{} {}\n{}\n{} {}\n", first, camera.width(), camera.height(),
                                       rectification, camera.width(), camera.height()));
}

}  // namespace nirslam
