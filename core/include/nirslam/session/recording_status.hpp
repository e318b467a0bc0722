#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace nirslam {

// What a recording is doing, for the operator: copied into every worker snapshot (small value).
struct RecordingStatus {
  enum class State {
    Off,        // no recording since the source was set
    Recording,  // frames are being written
    Stopped,    // ended normally (operator, end of source); the session is complete
    Failed,     // ended by an error (full disk, write error); every frame written before is kept
  };
  State state = State::Off;
  std::string folder;                  // the session folder
  std::int64_t frames_written = 0;     // durable: image synced and its journal line appended
  std::int64_t frames_dropped = 0;     // the writer's queue was full (never silent: also in session.json)
  std::int64_t queued = 0;             // waiting to be written
  std::uint64_t bytes_written = 0;     // frame files
  std::uint64_t free_bytes = 0;        // on the session's file system, at the last check
  std::optional<double> minutes_left;  // at the current write rate; unknown before the first second
  std::string message;                 // "recording to ...", "disk full: ...", ...
  std::string last_error;              // empty unless the recording failed
};

const char* to_string(RecordingStatus::State state);

}  // namespace nirslam
