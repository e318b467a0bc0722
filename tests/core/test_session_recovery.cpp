#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>

#include "core/test_session_support.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/session/session_recorder.hpp"
#include "nirslam/session/session_recovery.hpp"
#include "nirslam/session/session_source.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

RecorderOptions no_space_limits() {
  RecorderOptions options;
  options.min_free_bytes_to_start = 0;
  options.min_free_bytes_while_recording = 0;
  return options;
}

// The child records frame after frame and reports each index on `report_fd` once the recorder
// says it is durable; it never stops on its own.
[[noreturn]] void record_until_killed(const fs::path& session, int report_fd) {
  try {
    SessionRecorder recorder(session, {"test", "killed recorder", 30.0, nullptr}, no_space_limits());
    for (std::int64_t i = 0;; ++i) {
      recorder.record(synthetic_frame(i, 12, 160, 120));
      while (recorder.status().frames_written < i + 1) std::this_thread::sleep_for(200us);
      if (::write(report_fd, &i, sizeof i) != static_cast<ssize_t>(sizeof i)) ::_exit(3);
    }
  } catch (...) {
    ::_exit(2);
  }
}

TEST(SessionRecovery, SigkillMidSessionLosesNoFrameThatWasWritten) {
  const fs::path session = fresh_session_dir("sigkill") / "s";
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(pipe_fds[0]);
    record_until_killed(session, pipe_fds[1]);
  }
  ::close(pipe_fds[1]);
  std::int64_t last_durable = -1;
  while (last_durable < 14) {
    std::int64_t index = 0;
    ASSERT_EQ(::read(pipe_fds[0], &index, sizeof index), static_cast<ssize_t>(sizeof index)) << "the child died early";
    last_durable = index;
  }
  // Killed while it goes on writing: frames in flight, maybe a temp file or a torn journal line.
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  ::close(pipe_fds[0]);

  EXPECT_EQ(read_session_metadata(session).state, SessionState::Recording);
  EXPECT_THROW(SessionSource{session}, InputError) << "an unfinished session is not replayed before recovery";

  const RecoveryReport report = recover_session(session);
  EXPECT_TRUE(report.was_unfinished);
  EXPECT_GE(report.frames_kept, last_durable + 1) << report.summary;
  EXPECT_EQ(report.entries_without_image, 0) << report.summary;

  const SessionMetadata metadata = read_session_metadata(session);
  EXPECT_EQ(metadata.state, SessionState::Recovered);
  EXPECT_EQ(metadata.frames_written, report.frames_kept);
  EXPECT_EQ(metadata.width, 160);
  EXPECT_EQ(metadata.bit_depth, 12);
  EXPECT_EQ(metadata.recovery_report, report.summary);
  SessionSource replay(session);
  for (std::int64_t i = 0; i < report.frames_kept; ++i) {
    const std::optional<Frame> frame = replay.next();
    ASSERT_TRUE(frame);
    EXPECT_TRUE(same_pixels(frame->image, synthetic_frame(i, 12, 160, 120).image)) << "frame " << i;
    EXPECT_NEAR(frame->timestamp_s, synthetic_frame(i).timestamp_s, 1e-9);
  }
  EXPECT_FALSE(replay.next());
  for (const auto& item : fs::directory_iterator(session / "frames")) EXPECT_NE(item.path().extension(), ".tmp");
  EXPECT_FALSE(fs::exists(session / session_files::kReserve));
}

// Every kind of damage at once, made by hand on a finished recording.
TEST(SessionRecovery, RepairsTornLinePartialFilesAndMismatchesAndSaysSo) {
  const fs::path session = fresh_session_dir("damage") / "s";
  {
    SessionRecorder recorder(session, {"test", "damaged", 20.0, nullptr}, no_space_limits());
    for (int i = 0; i < 6; ++i) recorder.record(synthetic_frame(i));
    recorder.stop("end of source");
  }
  SessionMetadata metadata = read_session_metadata(session);
  metadata.state = SessionState::Recording;  // as a crash leaves it
  metadata.width = metadata.height = metadata.bit_depth = 0;
  write_session_metadata(session, metadata);
  std::ofstream(session / session_files::kJournal, std::ios::app) << "6,6,100.3,5.0,";  // torn
  std::ofstream(session / "frames/000006.png.tmp") << "partial";
  fs::copy_file(session / "frames/000005.png", session / "frames/000007.png");  // no journal line
  fs::remove(session / "frames/000003.png");                                     // a line without its image

  const RecoveryReport report = recover_session(session);
  EXPECT_TRUE(report.was_unfinished);
  EXPECT_EQ(report.frames_kept, 5);
  EXPECT_TRUE(report.torn_line_cut);
  EXPECT_EQ(report.temp_files_removed, 1);
  EXPECT_EQ(report.images_without_entry, 1);
  EXPECT_EQ(report.entries_without_image, 1);
  EXPECT_NE(report.summary.find("recovered 5 frames"), std::string::npos) << report.summary;
  EXPECT_NE(report.summary.find("torn journal line 8"), std::string::npos) << report.summary;

  // The journal reads strictly again, and the replay skips the lost frame 3.
  SessionSource replay(session);
  ASSERT_EQ(replay.journal().size(), 5u);
  EXPECT_EQ(replay.journal()[3].source_index, 4);
  EXPECT_EQ(replay.metadata().width, 64);
  for (int expected : {0, 1, 2, 4, 5}) EXPECT_TRUE(same_pixels(replay.next()->image, synthetic_frame(expected).image));
  EXPECT_FALSE(fs::exists(session / "frames/000007.png"));

  const RecoveryReport again = recover_session(session);
  EXPECT_FALSE(again.was_unfinished) << "a recovered session is left alone";
  EXPECT_EQ(again.frames_kept, 5);
}

TEST(SessionRecovery, OnStartEveryUnfinishedSessionOfTheFolderIsRecoveredAndOnlyThose) {
  const fs::path root = fresh_session_dir("root");
  for (const char* name : {"complete", "crashed"}) {
    SessionRecorder recorder(root / name, {"test", name, 20.0, nullptr}, no_space_limits());
    for (int i = 0; i < 3; ++i) recorder.record(synthetic_frame(i));
    recorder.stop("end of source");
  }
  SessionMetadata crashed = read_session_metadata(root / "crashed");
  crashed.state = SessionState::Recording;
  write_session_metadata(root / "crashed", crashed);
  fs::create_directories(root / "not_a_session");

  const std::vector<RecoveryReport> reports = recover_unfinished_sessions(root);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].folder, root / "crashed");
  EXPECT_EQ(reports[0].frames_kept, 3);
  EXPECT_EQ(read_session_metadata(root / "complete").state, SessionState::Complete);
  EXPECT_EQ(read_session_metadata(root / "crashed").state, SessionState::Recovered);
  EXPECT_TRUE(recover_unfinished_sessions(root / "missing").empty());
}

TEST(SessionRecovery, AFolderWithoutSessionMetadataIsNamed) {
  const fs::path folder = fresh_session_dir("no_metadata");
  try {
    recover_session(folder);
    FAIL() << "recovered a folder that is no session";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("session.json"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nirslam::testing
