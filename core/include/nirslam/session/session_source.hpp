#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "nirslam/session/session_format.hpp"
#include "nirslam/sources/source.hpp"

namespace nirslam {

// Replays a recorded session (kind "session"): the frames in journal order with their recorded
// timestamps, exposure, gain, illuminator power and ground-truth pose, and the session's camera.
// Speed is the worker's Pacing (recorded or as fast as possible). A session still in state
// "recording" is refused with a message pointing at `nirslam recover`.
class SessionSource final : public Source {
public:
  // Throws InputError naming the file (session.json, journal.csv, camera.txt) for a bad session.
  explicit SessionSource(const std::filesystem::path& folder);

  const SourceInfo& info() const override { return info_; }
  // Frame::index is the position in the session (0..n-1); a frame whose file is missing, damaged
  // or of another size than the first throws InputError naming the file.
  std::optional<Frame> next() override;
  void rewind() override { next_ = 0; }
  std::shared_ptr<const CameraModel> camera() const override { return camera_; }

  // The next next() returns the frame at this position; throws std::out_of_range past the end.
  void seek(std::size_t position) override;
  std::size_t position() const { return next_; }

  const SessionMetadata& metadata() const { return metadata_; }
  const std::vector<JournalEntry>& journal() const { return journal_; }
  const std::filesystem::path& folder() const { return folder_; }

private:
  std::filesystem::path folder_;
  SessionMetadata metadata_;
  std::vector<JournalEntry> journal_;
  std::shared_ptr<const CameraModel> camera_;
  SourceInfo info_;
  std::size_t next_ = 0;
};

// For SOURCE arguments (open_source, the command line): whether `path` is a recorded session, and
// the source for it.
std::unique_ptr<Source> open_session_source(const std::filesystem::path& folder);

}  // namespace nirslam
