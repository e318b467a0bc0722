#include "nirslam/session/session_recovery.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/session/session_format.hpp"

namespace nirslam {
namespace fs = std::filesystem;
namespace {

bool is_temp_file(const fs::path& file) { return file.extension() == session_files::kTempSuffix; }

int remove_temp_files(const fs::path& folder) {
  int removed = 0;
  std::error_code error;
  for (const auto& item : fs::directory_iterator(folder, error)) {
    if (item.is_regular_file() && is_temp_file(item.path()) && fs::remove(item.path(), error)) ++removed;
  }
  return removed;
}

// Cuts a text file after its last complete line (metrics.csv is appended row by row).
void cut_after_last_line_end(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return;
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  const std::size_t last = text.rfind('\n');
  const std::size_t keep = last == std::string::npos ? 0 : last + 1;
  if (keep != text.size()) fs::resize_file(file, keep);
}

}  // namespace

RecoveryReport recover_session(const fs::path& folder) {
  RecoveryReport report;
  report.folder = folder;
  SessionMetadata metadata = read_session_metadata(folder);
  if (metadata.state != SessionState::Recording) {
    report.frames_kept = metadata.frames_written;
    report.summary = fmt::format("{}: {} ({} frames), nothing to recover", folder.string(), to_string(metadata.state),
                                 metadata.frames_written);
    return report;
  }
  report.was_unfinished = true;
  const fs::path frames = folder / session_files::kFrames;
  report.temp_files_removed = remove_temp_files(folder) + remove_temp_files(frames);
  std::error_code error;
  if (fs::remove(folder / session_files::kReserve, error)) ++report.temp_files_removed;

  const fs::path journal_file = folder / session_files::kJournal;
  JournalContents journal;
  if (fs::exists(journal_file)) journal = read_journal(journal_file, true);
  report.torn_line_cut = journal.bad_line != 0;

  std::vector<JournalEntry> kept;
  std::set<std::string> referenced;
  for (const JournalEntry& entry : journal.entries) {
    const fs::path image = folder / entry.file;
    if (fs::is_regular_file(image, error) && fs::file_size(image, error) == entry.bytes) {
      kept.push_back(entry);
      referenced.insert(fs::path(entry.file).filename().string());
    } else {
      ++report.entries_without_image;
    }
  }
  // Images renamed into place just before the crash, without their journal line: no timestamp
  // nor exposure is known for them, so they go (the one frame being written may be lost).
  for (const auto& item : fs::directory_iterator(frames, error)) {
    if (item.is_regular_file() && !referenced.count(item.path().filename().string())) {
      fs::remove(item.path(), error);
      ++report.images_without_entry;
    }
  }

  if (report.torn_line_cut || report.entries_without_image > 0 || !fs::exists(journal_file)) {
    std::string text = std::string(kJournalHeader) + "\n";
    for (const JournalEntry& entry : kept) text += format_journal_line(entry);
    write_file_durably(journal_file, text);
  }
  cut_after_last_line_end(folder / session_files::kMetrics);

  if (!kept.empty() && metadata.width == 0) {
    // A damaged first frame leaves the size unknown (0), as a missing metadata file does.
    cv::Mat first;
    try {
      first = read_image(folder / kept.front().file);
    } catch (const std::runtime_error&) {
    }
    metadata.width = first.cols;
    metadata.height = first.rows;
    metadata.bit_depth = kept.front().bit_depth;
  }
  report.frames_kept = static_cast<std::int64_t>(kept.size());
  report.summary = fmt::format(
      "{}: recovered {} frames (removed {} partial files, {} images without a journal line, {} journal lines "
      "without an image{})",
      folder.string(), report.frames_kept, report.temp_files_removed, report.images_without_entry,
      report.entries_without_image,
      report.torn_line_cut ? fmt::format("; cut the torn journal line {}", journal.bad_line) : "");
  metadata.state = SessionState::Recovered;
  metadata.recovered_utc = utc_now_iso8601();
  metadata.frames_written = report.frames_kept;
  metadata.stop_reason = "interrupted while recording (crash, power cut or full disk)";
  metadata.recovery_report = report.summary;
  write_session_metadata(folder, metadata);
  spdlog::info("{}", report.summary);
  return report;
}

std::vector<RecoveryReport> recover_unfinished_sessions(const fs::path& sessions_root) {
  std::vector<RecoveryReport> reports;
  std::error_code error;
  if (!fs::is_directory(sessions_root, error)) return reports;
  for (const auto& item : fs::directory_iterator(sessions_root, error)) {
    if (!item.is_directory() || !is_session_folder(item.path())) continue;
    try {
      if (read_session_metadata(item.path()).state == SessionState::Recording)
        reports.push_back(recover_session(item.path()));
    } catch (const std::exception& e) {
      spdlog::error("cannot recover {}: {}", item.path().string(), e.what());
    }
  }
  return reports;
}

}  // namespace nirslam
