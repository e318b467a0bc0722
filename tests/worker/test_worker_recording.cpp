#include <cerrno>
#include <chrono>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "nirslam/session/session_format.hpp"
#include "nirslam/session/session_source.hpp"
#include "nirslam/sources/demo_source.hpp"
#include "nirslam/worker/worker.hpp"
#include "opencv_serial_under_tsan.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

fs::path fresh_folder(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("nirslam_worker_recording_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The quality stage only (the pipeline's stages have their own tests); small demo frames.
WorkerOptions recording_options() {
  WorkerOptions options;
  options.pipeline.mode = PipelineMode::Quality;
  options.recording.min_free_bytes_to_start = 0;
  options.recording.min_free_bytes_while_recording = 0;
  return options;
}

SourceFactory small_demo(std::int64_t frames) {
  return [frames] {
    DemoOptions demo;
    demo.width = 160;
    demo.height = 120;
    demo.frame_count = frames;
    return make_demo_source(demo);
  };
}


TEST(WorkerRecording, RecordsEveryFrameUntilTheEndOfTheSourceAndFinishesTheSession) {
  const fs::path session = fresh_folder("to_end") / "session";
  Worker worker(recording_options());
  worker.post(command::SetSource{small_demo(25)});
  worker.post(command::StartRecording{session, "bench test, lamp at 50 W"});
  auto started = worker.wait_for([](const Snapshot& s) { return s.recording.state != RecordingStatus::State::Off; }, 10s);
  ASSERT_EQ(started->recording.state, RecordingStatus::State::Recording) << started->recording.message;
  EXPECT_EQ(started->recording.folder, session.string());
  EXPECT_GT(started->recording.free_bytes, 0u);
  worker.post(command::Start{});
  const auto last = worker.wait_for(settled, 60s);
  ASSERT_EQ(last->state, WorkerState::Finished) << last->message;
  EXPECT_EQ(last->recording.state, RecordingStatus::State::Stopped) << last->recording.message;
  EXPECT_EQ(last->recording.frames_written, 25);
  EXPECT_EQ(last->recording.frames_dropped, 0);
  EXPECT_NE(last->message.find("recorded 25 frames"), std::string::npos) << last->message;

  const SessionMetadata metadata = read_session_metadata(session);
  EXPECT_EQ(metadata.state, SessionState::Complete);
  EXPECT_EQ(metadata.notes, "bench test, lamp at 50 W");
  EXPECT_EQ(metadata.stop_reason, "end of source");
  EXPECT_EQ(metadata.source_kind, "demo");
  SessionSource replay(session);
  ASSERT_EQ(replay.journal().size(), 25u);
  EXPECT_TRUE(replay.journal()[0].entropy_bits.has_value()) << "the worker's entropy goes into the journal";
  EXPECT_DOUBLE_EQ(*replay.journal()[0].illuminator_power_w, 50.0);
  std::ifstream metrics(session / session_files::kMetrics);
  int rows = 0;
  for (std::string line; std::getline(metrics, line);) ++rows;
  EXPECT_EQ(rows, 26) << "header + one metrics row per frame";
}

TEST(WorkerRecording, StopRecordingMidRunKeepsProcessing) {
  const fs::path session = fresh_folder("mid_run") / "session";
  WorkerOptions options = recording_options();
  options.pacing = Pacing::RecordedSpeed;  // 30 fps: time to stop in the middle
  Worker worker(options);
  worker.post(command::SetSource{small_demo(300)});
  worker.post(command::StartRecording{session, ""});
  worker.post(command::Start{});
  worker.wait_for([](const Snapshot& s) { return s.recording.frames_written >= 5; }, 30s);
  worker.post(command::StopRecording{});
  const auto stopped = worker.wait_for(
      [](const Snapshot& s) { return s.recording.state == RecordingStatus::State::Stopped; }, 30s);
  ASSERT_EQ(stopped->recording.state, RecordingStatus::State::Stopped) << stopped->recording.message;
  const std::int64_t written = stopped->recording.frames_written;
  EXPECT_GE(written, 5);
  const auto later = worker.wait_for([&](const Snapshot& s) { return s.frames_processed > stopped->frames_processed + 5; }, 30s);
  EXPECT_EQ(later->state, WorkerState::Running) << "processing goes on without the recording";
  EXPECT_EQ(later->recording.frames_written, written);
  EXPECT_EQ(read_session_metadata(session).stop_reason, "stopped by the operator");
  EXPECT_EQ(SessionSource(session).journal().size(), static_cast<std::size_t>(written));

  worker.post(command::StopRecording{});
  const auto refused = worker.wait_for([](const Snapshot& s) { return s.message == "no recording is running"; }, 10s);
  EXPECT_EQ(refused->message, "no recording is running");
}

// A recorded session replays seekable; while a new recording runs a jump is refused (the new
// session would get a gap), after it the jump is made.
TEST(WorkerRecording, ARecordedSessionSeeksButNotWhileRecording) {
  const fs::path base = fresh_folder("seek");
  {
    Worker recorder(recording_options());
    recorder.post(command::SetSource{small_demo(12)});
    recorder.post(command::StartRecording{base / "first", ""});
    recorder.post(command::Start{});
    ASSERT_EQ(recorder.wait_for(settled, 30s)->state, WorkerState::Finished);
  }
  Worker worker(recording_options());
  worker.post(command::SetSource{[base] { return open_session_source(base / "first"); }});
  worker.post(command::StartRecording{base / "second", ""});
  worker.post(command::Step{});
  ASSERT_TRUE(worker.wait_for([](const Snapshot& s) { return s.frames_processed == 1; }, 10s)->frame);
  worker.post(command::Seek{8});
  const auto refused = worker.wait_for([](const Snapshot& s) { return s.message.find("while recording") != std::string::npos; }, 10s);
  EXPECT_EQ(refused->message, "cannot jump while recording: stop the recording first");
  EXPECT_TRUE(refused->source.seekable);
  EXPECT_EQ(refused->frame->index, 0);

  worker.post(command::StopRecording{});
  worker.post(command::Seek{8});
  const auto moved = worker.wait_for([](const Snapshot& s) { return s.frame && s.frame->index == 8; }, 10s);
  ASSERT_TRUE(moved->frame);
  EXPECT_EQ(moved->frame->index, 8);
  EXPECT_EQ(moved->recording.frames_written, 1) << "nothing recorded after the recording stopped";
  EXPECT_EQ(SessionSource(base / "second").journal().size(), 1u);
}

TEST(WorkerRecording, AFolderThatIsNotEmptyIsRefusedWithAMessage) {
  const fs::path folder = fresh_folder("refused");
  std::ofstream(folder / "notes.txt") << "not a session";
  Worker worker(recording_options());
  worker.post(command::SetSource{small_demo(5)});
  worker.post(command::StartRecording{folder, ""});
  const auto refused = worker.wait_for([](const Snapshot& s) { return s.recording.state != RecordingStatus::State::Off; }, 10s);
  EXPECT_EQ(refused->recording.state, RecordingStatus::State::Failed);
  EXPECT_NE(refused->recording.last_error.find("not empty"), std::string::npos) << refused->recording.last_error;
  EXPECT_NE(refused->message.find("cannot start recording"), std::string::npos) << refused->message;
}

TEST(WorkerRecording, AFullDiskStopsTheRecordingNotThePipeline) {
  const fs::path session = fresh_folder("full_disk") / "session";
  WorkerOptions options = recording_options();
  options.recording.inject_write_error = [](const fs::path& file) { return file.filename() == "000010.png" ? ENOSPC : 0; };
  Worker worker(options);
  worker.post(command::SetSource{small_demo(40)});
  worker.post(command::StartRecording{session, ""});
  worker.post(command::Start{});
  const auto last = worker.wait_for(settled, 60s);
  EXPECT_EQ(last->state, WorkerState::Finished) << last->message;
  EXPECT_EQ(last->frames_processed, 40);
  EXPECT_EQ(last->recording.state, RecordingStatus::State::Failed);
  EXPECT_EQ(last->recording.frames_written, 10);
  EXPECT_NE(last->recording.message.find("disk full"), std::string::npos) << last->recording.message;
  EXPECT_NE(last->recording.message.find("10 frames written are kept"), std::string::npos) << last->recording.message;
  const SessionMetadata metadata = read_session_metadata(session);
  EXPECT_EQ(metadata.state, SessionState::Complete);
  EXPECT_EQ(metadata.frames_written, 10);
}

TEST(WorkerRecording, WithoutASourceNothingIsRecorded) {
  const fs::path session = fresh_folder("no_source") / "session";
  Worker worker(recording_options());
  worker.post(command::StartRecording{session, ""});
  const auto refused = worker.wait_for([](const Snapshot& s) { return !s.message.empty(); }, 10s);
  EXPECT_NE(refused->message.find("no source selected"), std::string::npos) << refused->message;
  EXPECT_FALSE(fs::exists(session));
}

}  // namespace
}  // namespace nirslam
