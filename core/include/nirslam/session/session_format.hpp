#pragma once
// A recorded session on disk (DESIGN.md, "Formats"; issue 11):
//
//   SESSION/session.json   metadata: state ("recording" while it is written, "complete" once the
//                          recorder stopped, "recovered" after recover_session repaired a session
//                          a crash left behind), software version, source, camera, image format,
//                          operator notes, start and stop time, frames written and dropped, why it
//                          stopped. Rewritten atomically (temp file, fsync, rename, fsync folder).
//   SESSION/journal.csv    one line per frame, appended only after the frame's image is durable:
//                          position, source index, timestamp, exposure, gain, illuminator power,
//                          entropy, bit depth, file, byte size, the odometry's pose when it had
//                          one and the source's ground-truth pose when it knows one (empty fields
//                          for unknowns). A crash can leave at most one torn last line.
//   SESSION/frames/        the frames, lossless: 000000.png ... (8- or 16-bit PNG) or .pgm (raw
//                          binary PGM, 16-bit big-endian as the format says), each written to a
//                          ".tmp" name, fsync'd and renamed.
//   SESSION/camera.txt     DSO camera file, when the source has a calibration
//   SESSION/metrics.csv    the per-frame metrics of the worker (MetricsCsvWriter), when recorded
//                          through the worker
//   SESSION/trajectory.txt, keyframes.txt, points.ply, calibration/   what the pipeline had when
//                          the recording ended (session/odometry_output, calibration_output)

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "nirslam/geometry/se3.hpp"

namespace nirslam {

class CameraModel;

namespace session_files {
inline constexpr const char* kMetadata = "session.json";
inline constexpr const char* kJournal = "journal.csv";
inline constexpr const char* kFrames = "frames";
inline constexpr const char* kCamera = "camera.txt";
inline constexpr const char* kMetrics = "metrics.csv";
inline constexpr const char* kTrajectory = "trajectory.txt";
inline constexpr const char* kKeyframes = "keyframes.txt";
inline constexpr const char* kPoints = "points.ply";
inline constexpr const char* kCalibration = "calibration";
// A few KiB kept free while recording and deleted before the final metadata is written, so a
// recording stopped by a full disk can still say so in session.json.
inline constexpr const char* kReserve = ".reserve";
inline constexpr const char* kTempSuffix = ".tmp";
}  // namespace session_files

enum class SessionState { Recording, Complete, Recovered };
const char* to_string(SessionState state);
std::optional<SessionState> parse_session_state(std::string_view text);

enum class FrameFileFormat { Png, Pgm };
const char* to_string(FrameFileFormat format);
const char* file_extension(FrameFileFormat format);  // ".png", ".pgm"
std::optional<FrameFileFormat> parse_frame_file_format(std::string_view text);

struct SessionMetadata {
  SessionState state = SessionState::Recording;
  std::string nirslam_version;
  std::string started_utc;   // ISO 8601, "2026-11-22T05:40:12Z"
  std::string stopped_utc;   // empty while recording
  std::string recovered_utc; // set by recover_session
  std::string notes;         // the operator's
  std::string source_kind;
  std::string source_description;
  double nominal_fps = 0.0;
  std::string camera;        // CameraModel::describe(), empty without a calibration
  int width = 0;             // of the frames, 0 until the first frame
  int height = 0;
  int bit_depth = 0;
  FrameFileFormat format = FrameFileFormat::Png;
  int png_compression = 1;
  std::int64_t frames_written = 0;
  std::int64_t frames_dropped = 0;            // queue overflow: the writer could not keep up
  std::vector<std::int64_t> dropped_indices;  // source indices of the dropped frames
  std::string stop_reason;                    // "end of source", "stopped", "disk full: ...", ...
  std::string recovery_report;                // what recover_session changed
  std::vector<std::string> outputs;           // trajectory.txt, calibration/, ... when written
};

nlohmann::json to_json(const SessionMetadata& metadata);
// Throws InputError naming the file and the field.
SessionMetadata metadata_from_json(const nlohmann::json& json, const std::filesystem::path& file);
SessionMetadata read_session_metadata(const std::filesystem::path& session_folder);
// Atomic and durable (write_file_durably). Throws std::system_error naming the file.
void write_session_metadata(const std::filesystem::path& session_folder, const SessionMetadata& metadata);

// One frame of the journal.
struct JournalEntry {
  std::int64_t position = 0;      // in the session, from 0; names the frame file
  std::int64_t source_index = 0;  // Frame::index at recording (gaps where frames were dropped)
  double timestamp_s = 0.0;
  std::optional<double> exposure_ms;
  std::optional<double> gain;
  std::optional<double> illuminator_power_w;
  std::optional<double> entropy_bits;
  int bit_depth = 8;
  std::string file;               // relative to the session folder: "frames/000042.png"
  std::uint64_t bytes = 0;        // size of the frame file
  std::optional<SE3> T_world_cam;        // the odometry's estimate, when it tracked the frame
  std::optional<SE3> T_world_cam_truth;  // the source's ground truth, when it has one
};

inline constexpr const char* kJournalHeader =
    "position,source_index,timestamp_s,exposure_ms,gain,illuminator_power_w,entropy_bits,bit_depth,file,bytes,"
    "tx,ty,tz,qx,qy,qz,qw,gt_tx,gt_ty,gt_tz,gt_qx,gt_qy,gt_qz,gt_qw";

// The line, '\n' included. Timestamps with 9 decimals, poses with 9 significant digits.
std::string format_journal_line(const JournalEntry& entry);
// Throws InputError naming the file, the line and the field.
JournalEntry parse_journal_line(std::string_view line, const std::filesystem::path& file, int line_number);

struct JournalContents {
  std::vector<JournalEntry> entries;
  std::uint64_t intact_bytes = 0;  // bytes up to the end of the last complete, well-formed line
  std::uint64_t file_bytes = 0;
  int bad_line = 0;                // first line that is torn or malformed, 0 when none
  std::string bad_line_error;
};

// Reads the journal. With `tolerate_damage`, stops at the first torn or malformed line and says
// where (for recovery); otherwise such a line throws InputError naming the file and line.
JournalContents read_journal(const std::filesystem::path& file, bool tolerate_damage = false);

// The frame file name of a position: "frames/000042.png".
std::string frame_file_name(std::int64_t position, FrameFileFormat format);

// Writes `bytes` to `file` so that after a crash the file either does not exist or is complete:
// to file + ".tmp", fsync, rename, fsync of the folder. The temp file is removed when a write
// fails. Throws std::system_error (code = errno, e.g. ENOSPC) with a message naming the file.
void write_file_durably(const std::filesystem::path& file, const void* bytes, std::size_t size);
void write_file_durably(const std::filesystem::path& file, std::string_view text);

// Free bytes for an unprivileged writer on the file system holding `path` (statvfs f_bavail).
// Throws std::system_error naming the path.
std::uint64_t free_bytes(const std::filesystem::path& path);
// "1.2 GiB", "340 MiB", "12 KiB".
std::string human_bytes(std::uint64_t bytes);
// Current UTC time in ISO 8601 with seconds.
std::string utc_now_iso8601();

// Whether `folder` looks like a recorded session (it holds session.json).
bool is_session_folder(const std::filesystem::path& folder);

// DSO camera.txt of any model CameraModel supports (the frames are recorded raw): rectification
// "none" for a pinhole, "crop" for a distorting lens, as DSO expects.
// Throws std::system_error naming the file when it cannot be written.
void write_session_camera_file(const std::filesystem::path& file, const CameraModel& camera);

}  // namespace nirslam
