#pragma once

#include <array>
#include <chrono>
#include <filesystem>
#include <future>
#include <optional>
#include <string>
#include <vector>

#include "nirslam/session/session_format.hpp"
#include "nirslam/worker/snapshot.hpp"
#include "ui/command_sink.hpp"
#include "ui/panels/session_panel.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// Record: capture what the operator sees into a session, and hand sessions on.
//   - the sessions folder, notes, Record / Stop (R), free space before recording starts,
//   - while recording: frames written, dropped, queued, bytes, free space and minutes left; a
//     full disk or write error in red (every frame written before it is kept),
//   - the recorded sessions in the folder (newest first): replay one (through the app, like any
//     source) or export it (TUM monoVO dataset, trajectory, report; optionally one zip) on a
//     background thread, the result shown when it is done.
// The recording itself runs in the worker (command::StartRecording); the panel never waits on it.
class RecordingPanel {
public:
  RecordingPanel();
  ~RecordingPanel();  // waits for an export still running, so it is never left half written
  RecordingPanel(const RecordingPanel&) = delete;
  RecordingPanel& operator=(const RecordingPanel&) = delete;

  void draw(const Snapshot& snapshot, const CommandSink& post, const SessionActions& actions);

  // Starts or stops recording (the R shortcut and the button).
  void toggle_recording(const Snapshot& snapshot, const CommandSink& post);

  void set_sessions_folder(const std::string& folder);
  std::string sessions_folder() const { return std::string(folder_.data()); }
  // Where a new session goes: SESSIONS/session-YYYYmmdd-HHMMSS (UTC).
  std::filesystem::path next_session_folder() const;

  struct SessionEntry {
    std::filesystem::path folder;
    SessionMetadata metadata;
  };
  // The folder's sessions as last scanned (rescanned every few seconds and after a recording).
  const std::vector<SessionEntry>& sessions() const { return sessions_; }
  void rescan() { next_scan_ = {}; }

  // Called with the export's outcome (for the notification area): success and one line.
  std::function<void(bool ok, const std::string& line)> on_export_done;

  // Geometry of the last draw, for the screenshot tests.
  const ScreenRect& record_button_rect() const { return record_button_; }
  const ScreenRect& status_rect() const { return status_; }
  const ScreenRect& sessions_rect() const { return sessions_rect_; }
  const std::string& export_result() const { return export_result_; }
  bool exporting() const { return export_job_.valid(); }
  // Blocks until a running export is done (tests).
  void wait_for_export();

private:
  void draw_controls(const Snapshot& snapshot, const CommandSink& post);
  void draw_status(const RecordingStatus& status);
  void draw_sessions(const SessionActions& actions);
  void scan_if_due();
  void start_export(const std::filesystem::path& session);
  void collect_export();

  std::array<char, 1024> folder_{};
  std::array<char, 512> notes_{};
  std::array<char, 1024> export_folder_{};
  bool export_archive_ = false;
  std::optional<std::uint64_t> free_bytes_;
  std::string free_error_;
  std::vector<SessionEntry> sessions_;
  int selected_ = -1;
  std::chrono::steady_clock::time_point next_scan_{};
  RecordingStatus::State last_state_ = RecordingStatus::State::Off;
  std::future<std::string> export_job_;  // the summary line, or throws the export's error
  std::string export_result_;
  bool export_failed_ = false;
  ScreenRect record_button_;
  ScreenRect status_;
  ScreenRect sessions_rect_;
};

// Where sessions go when the operator has not chosen: ~/nirslam-sessions.
std::filesystem::path default_sessions_folder();

}  // namespace nirslam::ui
