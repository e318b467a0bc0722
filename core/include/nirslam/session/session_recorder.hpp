#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "nirslam/image/frame.hpp"
#include "nirslam/session/recording_status.hpp"
#include "nirslam/session/session_format.hpp"

namespace nirslam {

class CameraModel;
class MetricsCsvWriter;
struct Snapshot;

struct RecorderOptions {
  FrameFileFormat format = FrameFileFormat::Png;
  // zlib level 0..9, and Huffman coding only (no string matching). Sensor noise leaves deflate's
  // matcher little to find: on the demo's noisy 640x480 frames Huffman-only at level 1 is both the
  // fastest and the smallest (8 bit: 4.2 ms and 139 KiB a frame; 16 bit: 8.5 ms and 386 KiB, one
  // core), against 5.6 ms / 166 KiB and 13 ms / 406 KiB for plain level 1
  // (tests/benchmarks/bench_recording.cpp).
  int png_compression = 1;
  bool png_huffman_only = true;
  std::size_t queue_capacity = 64;  // frames waiting for the disk (about 2 s at 30 fps)
  // Below this much free space a recording does not start (the error says how much is free).
  std::uint64_t min_free_bytes_to_start = 256ull << 20;
  // A recording stops cleanly once the free space falls below this, before the disk is full.
  std::uint64_t min_free_bytes_while_recording = 32ull << 20;
  std::string notes;  // the operator's, into session.json
  // Fault-injection seam for tests: called before every write of a session file (frame, journal,
  // metrics) with its path; a non-zero errno value (ENOSPC, EIO) makes that write fail exactly as
  // the operating system's would. Empty in production.
  std::function<int(const std::filesystem::path&)> inject_write_error;
};

// Where the frames come from, for session.json and camera.txt.
struct RecordingSourceInfo {
  std::string kind;
  std::string description;
  double nominal_fps = 0.0;
  std::shared_ptr<const CameraModel> camera;  // written as camera.txt when set
};

// What a frame's journal line carries beyond the Frame itself.
struct FrameAnnotations {
  std::optional<double> entropy_bits;
  std::optional<SE3> T_world_cam;  // the odometry's pose, when it tracked the frame
};

// Writes a session (session_format.hpp) on its own threads (one encodes, one writes and syncs):
// record() only queues the frame, so the caller (the worker) never waits on the disk. Each frame:
// encode, write durably (temp, fsync, rename), then append and sync its journal line, then its
// metrics row. A failed write (full disk)
// stops the recording with a message naming the file; every frame written before stays valid.
class SessionRecorder {
public:
  // Creates `folder` (it must not exist or be empty), checks the free space, writes session.json
  // (state "recording"), camera.txt and the journal header, and starts the writer thread.
  // Throws InputError naming the folder when it cannot start (not empty, too little free space:
  // the message says how much is free, a write fails).
  SessionRecorder(std::filesystem::path folder, RecordingSourceInfo source, RecorderOptions options = {});
  ~SessionRecorder();  // stop("recorder closed") when still recording
  SessionRecorder(const SessionRecorder&) = delete;
  SessionRecorder& operator=(const SessionRecorder&) = delete;

  // Queues the frame; returns false when it was not queued: the queue is full (counted as dropped,
  // logged, listed in session.json) or the recording has ended. The frame's pixel buffer is shared,
  // not copied: the caller must not write into it afterwards. With `metrics`, the snapshot's row is
  // written to metrics.csv after the frame.
  bool record(const Frame& frame, FrameAnnotations annotations = {}, std::shared_ptr<const Snapshot> metrics = nullptr);

  // Names an extra file the caller wrote into the session (trajectory.txt, calibration/), listed in
  // session.json at stop.
  void add_output(std::string name);

  // Writes what is queued, then the final session.json ("complete", the reason, counts). Blocks
  // until done; idempotent. Returns the final status.
  RecordingStatus stop(const std::string& reason);

  RecordingStatus status() const;
  bool recording() const;  // false once stopped or failed
  const std::filesystem::path& folder() const { return folder_; }

private:
  struct Item {
    Frame frame;
    FrameAnnotations annotations;
    std::shared_ptr<const Snapshot> metrics;
    std::vector<unsigned char> encoded;  // the file's bytes, once the encoder is through
  };

  void run_encoder();
  void run_writer();
  void write_item(Item& item);
  void append_journal(const std::string& line);
  void check_injected(const std::filesystem::path& file) const;
  void fail(const std::string& message);
  void refresh_free_space_locked(std::uint64_t free);

  std::filesystem::path folder_;
  RecorderOptions options_;
  SessionMetadata metadata_;  // writer thread until stop(), then the stopping thread
  int journal_fd_ = -1;
  std::uint64_t journal_bytes_ = 0;
  std::unique_ptr<MetricsCsvWriter> metrics_csv_;
  std::int64_t next_position_ = 0;
  std::chrono::steady_clock::time_point first_write_{};

  mutable std::mutex mutex_;
  std::condition_variable queue_cv_;
  std::deque<Item> queue_;    // waiting to be encoded (bounded by queue_capacity)
  std::condition_variable encoded_cv_;
  std::deque<Item> encoded_;  // encoded, waiting for the disk (at most 2)
  bool encoder_done_ = false;
  bool stop_requested_ = false;
  bool stopped_ = false;  // stop() finished
  RecordingStatus status_;
  std::vector<std::int64_t> dropped_indices_;
  std::vector<std::string> outputs_;
  std::thread encoder_thread_;  // last two: start after every member above exists
  std::thread writer_thread_;
};

}  // namespace nirslam
