#include "nirslam/session/session_recorder.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <system_error>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/session/metrics_csv_writer.hpp"
#include "nirslam/worker/snapshot.hpp"

namespace nirslam {
namespace fs = std::filesystem;
namespace {

constexpr std::size_t kReserveBytes = 64 * 1024;

std::vector<unsigned char> encode_frame(const cv::Mat& image, FrameFileFormat format, int png_compression,
                                        bool huffman_only) {
  try {
    if (format == FrameFileFormat::Pgm) return encode_pnm(image);
    return encode_png(image, {.compression_level = png_compression,
                              .strategy = huffman_only ? PngStrategy::HuffmanOnly : PngStrategy::Default});
  } catch (const std::exception& e) {
    throw std::runtime_error("cannot encode the frame as " + std::string(to_string(format)) + " (" + e.what() + ")");
  }
}

bool disk_full(const std::system_error& e) { return e.code().value() == ENOSPC || e.code().value() == EDQUOT; }

}  // namespace

const char* to_string(RecordingStatus::State state) {
  switch (state) {
    case RecordingStatus::State::Off: return "off";
    case RecordingStatus::State::Recording: return "recording";
    case RecordingStatus::State::Stopped: return "stopped";
    case RecordingStatus::State::Failed: return "failed";
  }
  return "unknown";
}

SessionRecorder::SessionRecorder(fs::path folder, RecordingSourceInfo source, RecorderOptions options)
    : folder_(std::move(folder)), options_(std::move(options)) {
  if (options_.png_compression < 0 || options_.png_compression > 9)
    throw InputError(folder_, "png_compression", fmt::format("expected 0..9, got {}", options_.png_compression));
  if (options_.queue_capacity == 0) throw InputError(folder_, "queue_capacity", "must be at least 1");
  std::error_code error;
  if (fs::exists(folder_, error) && !fs::is_empty(folder_, error))
    throw InputError(folder_, "the session folder exists and is not empty: choose a new folder");
  // The free space is checked before anything is created, on the nearest folder that exists.
  fs::path existing = fs::absolute(folder_, error);
  while (!existing.empty() && !fs::exists(existing, error) && existing != existing.parent_path())
    existing = existing.parent_path();
  try {
    status_.free_bytes = free_bytes(existing);
  } catch (const std::system_error& e) {
    throw InputError(folder_, std::string("cannot start recording: ") + e.what());
  }
  if (status_.free_bytes < options_.min_free_bytes_to_start)
    throw InputError(folder_, fmt::format("only {} free on this disk, below the {} a recording needs to start",
                                          human_bytes(status_.free_bytes), human_bytes(options_.min_free_bytes_to_start)));
  fs::create_directories(folder_ / session_files::kFrames, error);
  if (error) throw InputError(folder_, "cannot create the session folder: " + error.message());

  try {

    metadata_.nirslam_version = NIRSLAM_VERSION;
    metadata_.started_utc = utc_now_iso8601();
    metadata_.notes = options_.notes;
    metadata_.source_kind = source.kind;
    metadata_.source_description = source.description;
    metadata_.nominal_fps = source.nominal_fps;
    metadata_.format = options_.format;
    metadata_.png_compression = options_.png_compression;
    if (source.camera) {
      metadata_.camera = source.camera->describe();
      write_session_camera_file(folder_ / session_files::kCamera, *source.camera);
    }
    // The reserve first, so the final session.json fits even when the frames filled the disk.
    const std::string reserve(kReserveBytes, '\0');
    write_file_durably(folder_ / session_files::kReserve, reserve);
    write_file_durably(folder_ / session_files::kJournal, std::string(kJournalHeader) + "\n");
    journal_bytes_ = std::string(kJournalHeader).size() + 1;
    write_session_metadata(folder_, metadata_);
    const fs::path journal = folder_ / session_files::kJournal;
    journal_fd_ = ::open(journal.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
    if (journal_fd_ < 0) throw std::system_error(errno, std::generic_category(), journal.string() + ": cannot open");
  } catch (const std::system_error& e) {
    throw InputError(folder_, std::string("cannot start recording: ") + e.what());
  }
  status_.state = RecordingStatus::State::Recording;
  status_.folder = folder_.string();
  status_.message = "recording to " + folder_.string() + " (" + human_bytes(status_.free_bytes) + " free)";
  spdlog::info("{}", status_.message);
  encoder_thread_ = std::thread([this] { run_encoder(); });
  writer_thread_ = std::thread([this] { run_writer(); });
}

SessionRecorder::~SessionRecorder() {
  try {
    stop("recorder closed");
  } catch (const std::exception& e) {
    spdlog::error("{}: {}", folder_.string(), e.what());
  }
  if (journal_fd_ >= 0) ::close(journal_fd_);
}

bool SessionRecorder::record(const Frame& frame, FrameAnnotations annotations, std::shared_ptr<const Snapshot> metrics) {
  {
    std::lock_guard lock(mutex_);
    if (stop_requested_ || status_.state != RecordingStatus::State::Recording) return false;
    if (queue_.size() >= options_.queue_capacity) {
      ++status_.frames_dropped;
      dropped_indices_.push_back(frame.index);
      if (status_.frames_dropped == 1 || status_.frames_dropped % 100 == 0)
        spdlog::warn("{}: the disk does not keep up, frame {} dropped ({} dropped so far)", folder_.string(),
                     frame.index, status_.frames_dropped);
      return false;
    }
    queue_.push_back(Item{frame, annotations, std::move(metrics), {}});
    status_.queued = static_cast<std::int64_t>(queue_.size() + encoded_.size());
  }
  queue_cv_.notify_one();
  return true;
}

void SessionRecorder::add_output(std::string name) {
  std::lock_guard lock(mutex_);
  outputs_.push_back(std::move(name));
}

RecordingStatus SessionRecorder::status() const {
  std::lock_guard lock(mutex_);
  return status_;
}

bool SessionRecorder::recording() const {
  std::lock_guard lock(mutex_);
  return status_.state == RecordingStatus::State::Recording && !stop_requested_;
}

// Encoding (CPU) and the durable writes (mostly waiting for the disk to sync) run on two threads,
// so one frame is compressed while the one before is being synced: the throughput is that of the
// slower stage, not of both together.
void SessionRecorder::run_encoder() {
  while (true) {
    Item item;
    {
      std::unique_lock lock(mutex_);
      queue_cv_.wait(lock, [&] { return stop_requested_ || !queue_.empty(); });
      if (queue_.empty()) {
        encoder_done_ = true;  // stop requested and every frame handed on
        encoded_cv_.notify_all();
        return;
      }
      if (status_.state != RecordingStatus::State::Recording) {
        queue_.clear();  // a failure ended the recording; fail() counted these
        status_.queued = static_cast<std::int64_t>(encoded_.size());
        continue;
      }
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      item.encoded = encode_frame(item.frame.image, options_.format, options_.png_compression, options_.png_huffman_only);
    } catch (const std::exception& e) {
      fail(std::string("write failed: ") + e.what());
      continue;
    }
    std::unique_lock lock(mutex_);
    // At most two encoded frames wait for the disk; the rest wait unencoded in the queue.
    encoded_cv_.wait(lock, [&] { return encoded_.size() < 2 || status_.state != RecordingStatus::State::Recording; });
    if (status_.state != RecordingStatus::State::Recording) {
      // Encoded while a failure ended the recording: not written, so counted as dropped.
      ++status_.frames_dropped;
      dropped_indices_.push_back(item.frame.index);
      continue;
    }
    encoded_.push_back(std::move(item));
    encoded_cv_.notify_all();
  }
}

void SessionRecorder::run_writer() {
  while (true) {
    Item item;
    {
      std::unique_lock lock(mutex_);
      encoded_cv_.wait(lock, [&] { return encoder_done_ || !encoded_.empty(); });
      if (encoded_.empty()) return;  // the encoder is done and everything is written
      item = std::move(encoded_.front());
      encoded_.pop_front();
      encoded_cv_.notify_all();  // room for the encoder
    }
    try {
      write_item(item);
    } catch (const std::system_error& e) {
      fail(disk_full(e) ? std::string("disk full: ") + e.what() : std::string("write failed: ") + e.what());
    } catch (const std::exception& e) {
      fail(std::string("write failed: ") + e.what());
    }
  }
}

void SessionRecorder::check_injected(const fs::path& file) const {
  if (!options_.inject_write_error) return;
  if (const int code = options_.inject_write_error(file); code != 0)
    throw std::system_error(code, std::generic_category(), file.string() + ": cannot write");
}

void SessionRecorder::write_item(Item& item) {
  const Frame& frame = item.frame;
  const std::uint64_t free_before = free_bytes(folder_);
  if (free_before < options_.min_free_bytes_while_recording) {
    fail(fmt::format("disk almost full: {} free on {}, below the reserve of {}", human_bytes(free_before),
                     folder_.string(), human_bytes(options_.min_free_bytes_while_recording)));
    return;
  }
  JournalEntry entry;
  entry.position = next_position_;
  entry.source_index = frame.index;
  entry.timestamp_s = frame.timestamp_s;
  entry.exposure_ms = frame.exposure_ms;
  entry.gain = frame.gain;
  entry.illuminator_power_w = frame.illuminator_power_w;
  entry.entropy_bits = item.annotations.entropy_bits;
  entry.bit_depth = frame.bit_depth;
  entry.file = frame_file_name(next_position_, options_.format);
  entry.T_world_cam = item.annotations.T_world_cam;
  entry.T_world_cam_truth = frame.T_world_cam_truth;

  const std::vector<unsigned char>& bytes = item.encoded;
  entry.bytes = bytes.size();
  const fs::path image_file = folder_ / entry.file;
  check_injected(image_file);
  write_file_durably(image_file, bytes.data(), bytes.size());
  // Only now, with the image durable, does the journal say it exists.
  try {
    append_journal(format_journal_line(entry));
  } catch (...) {
    std::error_code ignored;
    fs::remove(image_file, ignored);  // no image without its journal line
    throw;
  }
  if (next_position_ == 0) {
    first_write_ = std::chrono::steady_clock::now();
    metadata_.width = frame.width();
    metadata_.height = frame.height();
    metadata_.bit_depth = frame.bit_depth;
  }
  ++next_position_;
  const std::uint64_t free = free_bytes(folder_);
  {
    std::lock_guard lock(mutex_);
    ++status_.frames_written;
    status_.bytes_written += bytes.size();
    status_.queued = static_cast<std::int64_t>(queue_.size() + encoded_.size());
    refresh_free_space_locked(free);
  }
  if (item.metrics) {
    check_injected(folder_ / session_files::kMetrics);
    if (!metrics_csv_) metrics_csv_ = std::make_unique<MetricsCsvWriter>(folder_ / session_files::kMetrics);
    metrics_csv_->write(*item.metrics);
  }
}

void SessionRecorder::refresh_free_space_locked(std::uint64_t free) {
  status_.free_bytes = free;
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - first_write_).count();
  if (status_.frames_written > 1 && elapsed_s >= 1.0 && status_.bytes_written > 0) {
    const double bytes_per_s = static_cast<double>(status_.bytes_written) / elapsed_s;
    const double usable = free > options_.min_free_bytes_while_recording
                              ? static_cast<double>(free - options_.min_free_bytes_while_recording)
                              : 0.0;
    status_.minutes_left = usable / bytes_per_s / 60.0;
  }
}

void SessionRecorder::append_journal(const std::string& line) {
  const fs::path journal = folder_ / session_files::kJournal;
  check_injected(journal);
  std::size_t done = 0;
  while (done < line.size()) {
    const ssize_t n = ::write(journal_fd_, line.data() + done, line.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int code = errno;
      // A torn line is cut off again, so the journal ends on a complete line.
      if (::ftruncate(journal_fd_, static_cast<off_t>(journal_bytes_)) != 0)
        spdlog::error("{}: cannot cut the torn line ({}); recover_session will", journal.string(), std::strerror(errno));
      throw std::system_error(code, std::generic_category(), journal.string() + ": cannot append");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fdatasync(journal_fd_) != 0) throw std::system_error(errno, std::generic_category(), journal.string() + ": cannot sync");
  journal_bytes_ += line.size();
}

void SessionRecorder::fail(const std::string& message) {
  std::lock_guard lock(mutex_);
  if (status_.state != RecordingStatus::State::Recording) return;
  const std::int64_t lost = static_cast<std::int64_t>(queue_.size() + encoded_.size());
  status_.state = RecordingStatus::State::Failed;
  status_.last_error = message;
  status_.message = fmt::format("recording stopped: {}; {} frames written are kept in {}", message,
                                status_.frames_written, folder_.string());
  if (lost > 0) {
    status_.frames_dropped += lost;
    for (const Item& item : encoded_) dropped_indices_.push_back(item.frame.index);
    for (const Item& item : queue_) dropped_indices_.push_back(item.frame.index);
    encoded_.clear();
    status_.message += fmt::format(" ({} queued frames not written)", lost);
  }
  spdlog::error("{}", status_.message);
  encoded_cv_.notify_all();
}

RecordingStatus SessionRecorder::stop(const std::string& reason) {
  {
    std::lock_guard lock(mutex_);
    if (stopped_) return status_;
    stop_requested_ = true;
  }
  queue_cv_.notify_all();
  if (encoder_thread_.joinable()) encoder_thread_.join();
  if (writer_thread_.joinable()) writer_thread_.join();

  std::lock_guard lock(mutex_);
  stopped_ = true;
  const bool failed = status_.state == RecordingStatus::State::Failed;
  metadata_.state = SessionState::Complete;
  metadata_.stopped_utc = utc_now_iso8601();
  metadata_.frames_written = status_.frames_written;
  metadata_.frames_dropped = status_.frames_dropped;
  metadata_.dropped_indices = dropped_indices_;
  metadata_.stop_reason = failed ? status_.last_error : reason;
  metadata_.outputs = outputs_;
  std::error_code ignored;
  fs::remove(folder_ / session_files::kReserve, ignored);  // room for session.json on a full disk
  try {
    write_session_metadata(folder_, metadata_);
  } catch (const std::system_error& e) {
    // The frames and the journal are intact; the next start's recovery pass completes the session.
    status_.state = RecordingStatus::State::Failed;
    status_.last_error = e.what();
    status_.message = fmt::format("{} frames kept in {}, but session.json could not be finished ({}): "
                                  "`nirslam recover` repairs it", status_.frames_written, folder_.string(), e.what());
    spdlog::error("{}", status_.message);
    return status_;
  }
  if (!failed) {
    status_.state = RecordingStatus::State::Stopped;
    status_.message = fmt::format("recorded {} frames ({}) to {}{}", status_.frames_written,
                                  human_bytes(status_.bytes_written), folder_.string(),
                                  status_.frames_dropped > 0 ? fmt::format(", {} dropped", status_.frames_dropped) : "");
  }
  status_.queued = 0;
  spdlog::info("{}", status_.message);
  return status_;
}

}  // namespace nirslam
