#include "nirslam/session/session_source.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include "nirslam/camera/camera_io.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {
namespace fs = std::filesystem;

SessionSource::SessionSource(const fs::path& folder) : folder_(folder) {
  metadata_ = read_session_metadata(folder_);
  if (metadata_.state == SessionState::Recording)
    throw InputError(folder_ / session_files::kMetadata, "state",
                     "the session is still 'recording' (being recorded, or interrupted): run `nirslam recover " +
                         folder_.string() + "` first");
  journal_ = read_journal(folder_ / session_files::kJournal).entries;
  const fs::path camera_file = folder_ / session_files::kCamera;
  if (fs::exists(camera_file)) camera_ = read_dso_camera_file(camera_file).input;
  info_.kind = "session";
  info_.description = folder_.string();
  info_.frame_count = journal_.size();
  info_.seekable = true;
  info_.nominal_fps = metadata_.nominal_fps;
  info_.reports_lamp_power = std::any_of(journal_.begin(), journal_.end(), [](const JournalEntry& e) {
    return e.illuminator_power_w && *e.illuminator_power_w > 0.0;
  });
  if (info_.nominal_fps <= 0.0 && journal_.size() > 1) {
    const double span = journal_.back().timestamp_s - journal_.front().timestamp_s;
    if (span > 0.0) info_.nominal_fps = static_cast<double>(journal_.size() - 1) / span;
  }
}

std::optional<Frame> SessionSource::next() {
  if (next_ >= journal_.size()) return std::nullopt;
  const JournalEntry& entry = journal_[next_];
  const fs::path file = folder_ / entry.file;
  Frame frame;
  frame.image = read_image(file);  // InputError naming the file: missing, empty or damaged
  const int expected_type = entry.bit_depth > 8 ? CV_16UC1 : CV_8UC1;
  if (frame.image.type() != expected_type)
    throw InputError(file, fmt::format("expected a {}-bit grey image as the journal says", entry.bit_depth > 8 ? 16 : 8));
  if (metadata_.width > 0 && (frame.image.cols != metadata_.width || frame.image.rows != metadata_.height))
    throw InputError(file, fmt::format("{}x{} pixels, the session's frames are {}x{}", frame.image.cols,
                                       frame.image.rows, metadata_.width, metadata_.height));
  frame.bit_depth = entry.bit_depth;
  frame.timestamp_s = entry.timestamp_s;
  frame.index = static_cast<std::int64_t>(next_);
  frame.exposure_ms = entry.exposure_ms;
  frame.gain = entry.gain;
  frame.illuminator_power_w = entry.illuminator_power_w;
  frame.T_world_cam_truth = entry.T_world_cam_truth;
  frame.name = file.string();
  ++next_;
  return frame;
}

void SessionSource::seek(std::size_t position) {
  if (position >= journal_.size())
    throw std::out_of_range(fmt::format("{}: cannot seek to frame {}, the session has {} frames", folder_.string(),
                                        position, journal_.size()));
  next_ = position;
}

std::unique_ptr<Source> open_session_source(const fs::path& folder) { return std::make_unique<SessionSource>(folder); }

}  // namespace nirslam
