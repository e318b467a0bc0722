#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "core/test_session_support.hpp"
#include "nirslam/camera/camera_model.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/session/session_recorder.hpp"
#include "nirslam/session/session_source.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

RecorderOptions test_options() {
  RecorderOptions options;
  options.min_free_bytes_to_start = 0;
  options.min_free_bytes_while_recording = 0;
  return options;
}

RecordingSourceInfo test_source() { return {"test", "synthetic frames", 20.0, nullptr}; }

void expect_round_trip(int bit_depth, FrameFileFormat format) {
  const fs::path session = fresh_session_dir(fmt::format("round_trip_{}_{}", bit_depth, to_string(format))) / "s";
  RecorderOptions options = test_options();
  options.format = format;
  options.notes = "left tunnel, wet walls";
  const int n = 12;
  {
    SessionRecorder recorder(session, test_source(), options);
    for (int i = 0; i < n; ++i) {
      FrameAnnotations annotations;
      annotations.entropy_bits = 6.5 + 0.01 * i;
      if (i >= 3) annotations.T_world_cam = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i, 0.0, 0.0));
      ASSERT_TRUE(recorder.record(synthetic_frame(i, bit_depth), annotations));
    }
    const RecordingStatus status = recorder.stop("end of source");
    EXPECT_EQ(status.state, RecordingStatus::State::Stopped) << status.message;
    EXPECT_EQ(status.frames_written, n);
    EXPECT_EQ(status.frames_dropped, 0);
    EXPECT_GT(status.bytes_written, 0u);
  }
  const SessionMetadata metadata = read_session_metadata(session);
  EXPECT_EQ(metadata.state, SessionState::Complete);
  EXPECT_EQ(metadata.nirslam_version, NIRSLAM_VERSION);
  EXPECT_EQ(metadata.notes, "left tunnel, wet walls");
  EXPECT_EQ(metadata.frames_written, n);
  EXPECT_EQ(metadata.width, 64);
  EXPECT_EQ(metadata.height, 48);
  EXPECT_EQ(metadata.bit_depth, bit_depth);
  EXPECT_EQ(metadata.stop_reason, "end of source");
  EXPECT_EQ(metadata.source_kind, "test");
  EXPECT_FALSE(metadata.started_utc.empty());
  EXPECT_FALSE(metadata.stopped_utc.empty());
  EXPECT_FALSE(fs::exists(session / session_files::kReserve));

  SessionSource source(session);
  EXPECT_TRUE(source.info().reports_lamp_power) << "its frames carry the lamp's power";
  for (int i = 0; i < n; ++i) {
    const std::optional<Frame> frame = source.next();
    ASSERT_TRUE(frame) << i;
    const Frame expected = synthetic_frame(i, bit_depth);
    EXPECT_TRUE(same_pixels(frame->image, expected.image)) << "frame " << i << " is not bit-identical";
    EXPECT_EQ(frame->bit_depth, bit_depth);
    EXPECT_EQ(frame->index, i);
    EXPECT_NEAR(frame->timestamp_s, expected.timestamp_s, 1e-9);
    EXPECT_DOUBLE_EQ(*frame->exposure_ms, *expected.exposure_ms);
    EXPECT_DOUBLE_EQ(*frame->gain, 2.0);
    EXPECT_DOUBLE_EQ(*frame->illuminator_power_w, *expected.illuminator_power_w);
    ASSERT_TRUE(frame->T_world_cam_truth);
    EXPECT_TRUE(frame->T_world_cam_truth->translation().isApprox(expected.T_world_cam_truth->translation(), 1e-8));
    const JournalEntry& entry = source.journal()[static_cast<std::size_t>(i)];
    EXPECT_NEAR(*entry.entropy_bits, 6.5 + 0.01 * i, 1e-9);
    EXPECT_EQ(entry.T_world_cam.has_value(), i >= 3);
  }
  EXPECT_FALSE(source.next());
}

TEST(SessionRecorder, EightBitPngRoundTripIsBitIdenticalWithItsMetadata) { expect_round_trip(8, FrameFileFormat::Png); }
TEST(SessionRecorder, SixteenBitPngRoundTripIsBitIdenticalWithItsMetadata) { expect_round_trip(12, FrameFileFormat::Png); }
TEST(SessionRecorder, RawPgmRoundTripIsBitIdentical) {
  expect_round_trip(8, FrameFileFormat::Pgm);
  expect_round_trip(16, FrameFileFormat::Pgm);
}

TEST(SessionRecorder, WritesTheCameraAndReplaysIt) {
  const fs::path session = fresh_session_dir("camera") / "s";
  RecordingSourceInfo source = test_source();
  source.camera = std::make_shared<PinholeCamera>(64, 48, Eigen::Vector4d(50.5, 51.25, 31.5, 23.75));
  {
    SessionRecorder recorder(session, source, test_options());
    recorder.record(synthetic_frame(0));
    recorder.stop("done");
  }
  SessionSource replay(session);
  ASSERT_TRUE(replay.camera());
  EXPECT_DOUBLE_EQ(replay.camera()->fx(), 50.5);
  EXPECT_DOUBLE_EQ(replay.camera()->cy(), 23.75);
  EXPECT_EQ(replay.camera()->width(), 64);
}

TEST(SessionRecorder, RefusesAFolderThatIsNotEmpty) {
  const fs::path session = fresh_session_dir("not_empty");
  std::ofstream(session / "something.txt") << "keep me";
  try {
    SessionRecorder recorder(session, test_source(), test_options());
    FAIL() << "recorded into a folder that holds other files";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not empty"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(session / "something.txt"));
}

TEST(SessionRecorder, RefusesToStartOnAFullDiskAndSaysHowMuchIsFree) {
  const fs::path session = fresh_session_dir("too_little_space") / "s";
  RecorderOptions options = test_options();
  options.min_free_bytes_to_start = std::uint64_t{1} << 62;  // 4 EiB: more than any disk here
  try {
    SessionRecorder recorder(session, test_source(), options);
    FAIL() << "started without enough free space";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(" free on this disk"), std::string::npos) << message;
    EXPECT_NE(message.find("iB"), std::string::npos) << "names the free space in bytes units: " << message;
  }
}

TEST(SessionRecorder, StatusReportsFreeSpaceAndMinutesLeft) {
  const fs::path session = fresh_session_dir("status") / "s";
  SessionRecorder recorder(session, test_source(), test_options());
  EXPECT_GT(recorder.status().free_bytes, 0u);
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; std::chrono::steady_clock::now() - start < 1200ms; ++i) {
    recorder.record(synthetic_frame(i));
    std::this_thread::sleep_for(20ms);
  }
  const RecordingStatus status = recorder.status();
  EXPECT_EQ(status.state, RecordingStatus::State::Recording);
  EXPECT_GT(status.frames_written, 10);
  ASSERT_TRUE(status.minutes_left) << "known after a second of recording";
  EXPECT_GT(*status.minutes_left, 1.0);
  recorder.stop("done");
}

// The fault-injection seam: the frame file of position 5 fails with ENOSPC, as on a full disk.
TEST(SessionRecorder, InjectedFullDiskStopsWithAClearMessageAndKeepsWhatWasWritten) {
  const fs::path session = fresh_session_dir("enospc_seam") / "s";
  RecorderOptions options = test_options();
  options.inject_write_error = [](const fs::path& file) { return file.filename() == "000005.png" ? ENOSPC : 0; };
  SessionRecorder recorder(session, test_source(), options);
  for (int i = 0; i < 10; ++i) {
    recorder.record(synthetic_frame(i));
    std::this_thread::sleep_for(2ms);
  }
  const RecordingStatus status = recorder.stop("end of source");
  EXPECT_EQ(status.state, RecordingStatus::State::Failed);
  EXPECT_EQ(status.frames_written, 5);
  EXPECT_NE(status.message.find("disk full"), std::string::npos) << status.message;
  EXPECT_NE(status.message.find("000005.png"), std::string::npos) << "names the file: " << status.message;
  EXPECT_NE(status.message.find("5 frames written are kept"), std::string::npos) << status.message;
  EXPECT_FALSE(recorder.record(synthetic_frame(11))) << "a failed recording takes no more frames";

  const SessionMetadata metadata = read_session_metadata(session);
  EXPECT_EQ(metadata.state, SessionState::Complete);
  EXPECT_NE(metadata.stop_reason.find("disk full"), std::string::npos) << metadata.stop_reason;
  EXPECT_EQ(metadata.frames_written, 5);
  SessionSource replay(session);
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(same_pixels(replay.next()->image, synthetic_frame(i).image)) << i;
  EXPECT_FALSE(replay.next());
  EXPECT_FALSE(fs::exists(session / "frames/000005.png"));
  EXPECT_FALSE(fs::exists(session / "frames/000005.png.tmp"));
}

TEST(SessionRecorder, InjectedJournalFailureLeavesNoImageWithoutJournalLine) {
  const fs::path session = fresh_session_dir("journal_eio") / "s";
  RecorderOptions options = test_options();
  int journal_writes = 0;
  options.inject_write_error = [&journal_writes](const fs::path& file) {
    return file.filename() == session_files::kJournal && ++journal_writes == 3 ? EIO : 0;
  };
  SessionRecorder recorder(session, test_source(), options);
  for (int i = 0; i < 5; ++i) recorder.record(synthetic_frame(i));
  const RecordingStatus status = recorder.stop("end of source");
  EXPECT_EQ(status.state, RecordingStatus::State::Failed);
  EXPECT_EQ(status.frames_written, 2);
  EXPECT_NE(status.message.find("write failed"), std::string::npos) << status.message;
  EXPECT_NE(status.message.find("journal.csv"), std::string::npos) << status.message;
  EXPECT_EQ(SessionSource(session).journal().size(), 2u);
  EXPECT_FALSE(fs::exists(session / "frames/000002.png")) << "its journal line failed, so the image goes too";
}

TEST(SessionRecorder, QueueOverflowIsCountedAndListedNeverSilent) {
  const fs::path session = fresh_session_dir("overflow") / "s";
  RecorderOptions options = test_options();
  options.queue_capacity = 2;
  options.inject_write_error = [](const fs::path& file) {
    if (file.extension() == ".png") std::this_thread::sleep_for(30ms);  // a slow disk
    return 0;
  };
  SessionRecorder recorder(session, test_source(), options);
  int accepted = 0;
  for (int i = 0; i < 20; ++i) accepted += recorder.record(synthetic_frame(i)) ? 1 : 0;
  const RecordingStatus status = recorder.stop("end of source");
  EXPECT_EQ(status.state, RecordingStatus::State::Stopped);
  EXPECT_GT(status.frames_dropped, 0);
  EXPECT_EQ(status.frames_written, accepted);
  EXPECT_EQ(status.frames_written + status.frames_dropped, 20);
  EXPECT_NE(status.message.find("dropped"), std::string::npos) << status.message;
  const SessionMetadata metadata = read_session_metadata(session);
  EXPECT_EQ(metadata.frames_dropped, status.frames_dropped);
  EXPECT_EQ(static_cast<std::int64_t>(metadata.dropped_indices.size()), status.frames_dropped);
}

// A real full disk: a 2 MiB tmpfs (needs root; skipped with the reason otherwise).
class SessionRecorderOnTmpfs : public ::testing::Test {
protected:
  void SetUp() override {
    // One mount point per test: ctest runs the two at once (-j2), and a shared one was busy.
    mount_point_ = fresh_session_dir(std::string("tmpfs_mount_") +
                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    if (::mount("tmpfs", mount_point_.c_str(), "tmpfs", 0, "size=2m") != 0)
      GTEST_SKIP() << "cannot mount a 2 MiB tmpfs at " << mount_point_ << " (" << std::strerror(errno)
                   << "): the full-disk test needs root (CI runs as root)";
    mounted_ = true;
  }
  void TearDown() override {
    if (mounted_) ::umount(mount_point_.c_str());
  }
  fs::path mount_point_;
  bool mounted_ = false;
};

TEST_F(SessionRecorderOnTmpfs, FullDiskStopsRecordingAndKeepsEveryFrameWritten) {
  const fs::path session = mount_point_ / "session";
  SessionRecorder recorder(session, test_source(), test_options());
  int queued = 0;
  // 640x480 noise: ~300 KiB a PNG, so the 2 MiB disk fills after a handful of frames.
  for (int i = 0; i < 40 && recorder.recording(); ++i) {
    queued += recorder.record(synthetic_frame(i, 8, 640, 480)) ? 1 : 0;
    std::this_thread::sleep_for(5ms);
  }
  const RecordingStatus status = recorder.stop("end of source");
  EXPECT_EQ(status.state, RecordingStatus::State::Failed) << status.message;
  EXPECT_NE(status.message.find("disk full"), std::string::npos) << status.message;
  EXPECT_NE(status.message.find("No space left on device"), std::string::npos) << status.message;
  EXPECT_GT(status.frames_written, 0);
  EXPECT_LT(status.frames_written, queued);

  // session.json was still finished (the reserve made room for it), and every frame is intact.
  const SessionMetadata metadata = read_session_metadata(session);
  EXPECT_EQ(metadata.state, SessionState::Complete);
  EXPECT_EQ(metadata.frames_written, status.frames_written);
  SessionSource replay(session);
  ASSERT_EQ(replay.journal().size(), static_cast<std::size_t>(status.frames_written));
  for (std::int64_t i = 0; i < status.frames_written; ++i)
    EXPECT_TRUE(same_pixels(replay.next()->image, synthetic_frame(i, 8, 640, 480).image)) << i;
  for (const auto& item : fs::directory_iterator(session / "frames"))
    EXPECT_NE(item.path().extension(), ".tmp") << "partial file left: " << item.path();
}

TEST_F(SessionRecorderOnTmpfs, StopsCleanlyBeforeTheDiskIsFull) {
  const fs::path session = mount_point_ / "session";
  RecorderOptions options = test_options();
  options.min_free_bytes_while_recording = 1u << 20;  // keep 1 MiB free
  SessionRecorder recorder(session, test_source(), options);
  for (int i = 0; i < 40 && recorder.recording(); ++i) {
    recorder.record(synthetic_frame(i, 8, 640, 480));
    std::this_thread::sleep_for(5ms);
  }
  const RecordingStatus status = recorder.stop("end of source");
  EXPECT_EQ(status.state, RecordingStatus::State::Failed);
  EXPECT_NE(status.message.find("disk almost full"), std::string::npos) << status.message;
  EXPECT_GT(status.frames_written, 0);
  EXPECT_EQ(SessionSource(session).journal().size(), static_cast<std::size_t>(status.frames_written));
}

}  // namespace
}  // namespace nirslam::testing
