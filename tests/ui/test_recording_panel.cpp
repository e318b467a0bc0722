// The Record tab rendered headless: Record posts StartRecording into a new folder under the
// sessions folder (with the notes), Stop posts StopRecording, the recording status is drawn (a
// failure in red), the control bar shows a REC badge, and the recorded sessions of the folder are
// listed; Replay hands "session:FOLDER" to the app and Export writes a real dataset in the
// background, the result shown when it is done.

#include <filesystem>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/session/session_recorder.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"
#include "ui/application.hpp"
#include "ui/gl/shader.hpp"
#include "ui/panels/control_bar.hpp"
#include "ui/panels/recording_panel.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

namespace fs = std::filesystem;
using testing::full_window;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("nirslam_record_panel_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A real three-frame session, recorded through the project's recorder.
fs::path record_session(const fs::path& folder) {
  RecordingSourceInfo info;
  info.kind = "test";
  info.description = "three hand-made frames";
  SessionRecorder recorder(folder, info);
  for (int i = 0; i < 3; ++i) {
    Frame frame;
    frame.image = cv::Mat(48, 64, CV_8UC1, cv::Scalar(40 + 60 * i));
    frame.index = i;
    frame.timestamp_s = 0.05 * i;
    frame.exposure_ms = 4.0 + i;
    recorder.record(frame);
  }
  recorder.stop("end of source");
  return folder;
}

Snapshot running() {
  Snapshot s;
  s.state = WorkerState::Running;
  s.source.kind = "sim";
  s.source.description = "simulated tunnel";
  return s;
}

class RecordingPanelTest : public testing::HeadlessGlTest {
protected:
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ui_ = std::make_unique<OffscreenUi>(1100, 320);
    panel_ = std::make_unique<RecordingPanel>();
  }
  void TearDown() override {
    panel_.reset();
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  void draw(const Snapshot& snapshot) {
    ui_->frame([&] { full_window([&] { panel_->draw(snapshot, sink_, actions_); }); });
  }
  void click(ImVec2 at, const Snapshot& snapshot) {
    testing::click_at(at, [&] { draw(snapshot); });
  }
  std::unique_ptr<OffscreenUi> ui_;
  std::unique_ptr<RecordingPanel> panel_;
  std::vector<Command> posted_;
  std::vector<std::string> opened_;
  CommandSink sink_ = [this](Command c) { posted_.push_back(std::move(c)); };
  SessionActions actions_{[this](const std::string& source) {
                             opened_.push_back(source);
                             return std::string();
                           },
                           {}, {}};
};

TEST_F(RecordingPanelTest, RecordPostsStartIntoTheSessionsFolderAndStopEndsIt) {
  const fs::path root = fresh_dir("start");
  panel_->set_sessions_folder(root.string());
  Snapshot snapshot = running();
  draw(snapshot);
  ASSERT_FALSE(panel_->record_button_rect().empty());
  click(panel_->record_button_rect().centre(), snapshot);
  ASSERT_EQ(posted_.size(), 1u);
  const auto* start = std::get_if<command::StartRecording>(&posted_[0]);
  ASSERT_NE(start, nullptr);
  EXPECT_EQ(start->folder.parent_path(), root);
  EXPECT_EQ(start->folder.filename().string().rfind("session-", 0), 0u) << start->folder;

  // The worker reports it is recording: the button stops it, the status is drawn.
  snapshot.recording.state = RecordingStatus::State::Recording;
  snapshot.recording.folder = start->folder.string();
  snapshot.recording.frames_written = 120;
  snapshot.recording.free_bytes = 5ull << 30;
  snapshot.recording.minutes_left = 42.0;
  snapshot.recording.message = "recording to " + start->folder.string();
  posted_.clear();
  draw(snapshot);
  click(panel_->record_button_rect().centre(), snapshot);
  ASSERT_EQ(posted_.size(), 1u);
  EXPECT_TRUE(std::holds_alternative<command::StopRecording>(posted_[0]));
  const cv::Mat rgba = ui_->read_rgba();
  testing::save_if_requested(rgba, "RecordingStatus");
  EXPECT_GT(testing::count_colour(rgba, panel_->status_rect(), colours::saturated, 30), 20) << "red 'recording' badge";
  EXPECT_GT(testing::grey_stddev(rgba, panel_->status_rect()), 8.0) << "status rows are written";
}

TEST_F(RecordingPanelTest, FullDiskIsShownInRed) {
  Snapshot snapshot = running();
  snapshot.recording.state = RecordingStatus::State::Failed;
  snapshot.recording.folder = "/media/usb/session-1";
  snapshot.recording.frames_written = 3001;
  snapshot.recording.last_error = "disk full writing /media/usb/session-1/frames/003001.png: 3001 frames kept";
  draw(snapshot);
  draw(snapshot);
  const cv::Mat rgba = ui_->read_rgba();
  testing::save_if_requested(rgba, "RecordingFailed");
  EXPECT_GT(testing::count_colour(rgba, panel_->status_rect(), colours::state_failed, 40), 60);
}

TEST_F(RecordingPanelTest, SessionsAreListedReplayedAndExported) {
  const fs::path root = fresh_dir("list");
  const fs::path session = record_session(root / "session-20261122-060000");
  panel_->set_sessions_folder(root.string());
  Snapshot snapshot = running();
  draw(snapshot);
  ASSERT_EQ(panel_->sessions().size(), 1u);
  EXPECT_EQ(panel_->sessions()[0].metadata.frames_written, 3);
  // Select the row, then Replay (the first button under the list).
  const ScreenRect list = panel_->sessions_rect();
  click(ImVec2(list.min.x + 20.0f, list.min.y + 0.5f * ImGui::GetTextLineHeightWithSpacing()), snapshot);
  const float buttons_y = list.max.y + 0.5f * ImGui::GetFrameHeight() + ImGui::GetStyle().ItemSpacing.y;
  click(ImVec2(list.min.x + 10.0f, buttons_y), snapshot);
  ASSERT_EQ(opened_.size(), 1u);
  EXPECT_EQ(opened_[0], "session:" + session.string());

  // Export to the default folder (SESSION-export) on a background thread.
  const float export_x = list.min.x + ImGui::CalcTextSize("Replay").x + 2.0f * ImGui::GetStyle().FramePadding.x +
                         ImGui::GetStyle().ItemSpacing.x + 12.0f;
  click(ImVec2(export_x, buttons_y), snapshot);
  panel_->wait_for_export();
  draw(snapshot);
  EXPECT_NE(panel_->export_result().find("Exported 3 frames"), std::string::npos) << panel_->export_result();
  TumMonoVoReader reader(session.string() + "-export");
  int frames = 0;
  while (reader.next()) ++frames;
  EXPECT_EQ(frames, 3);
  testing::save_if_requested(ui_->read_rgba(), "RecordingSessions");
}

class RecBadgeTest : public testing::HeadlessGlTest {};

TEST_F(RecBadgeTest, ControlBarShowsRecWhileRecording) {
  OffscreenUi offscreen(1280, 800);
  Application app(gl::find_shader_dir(), {});
  Snapshot snapshot = running();
  snapshot.recording.state = RecordingStatus::State::Recording;
  snapshot.recording.frames_written = 77;
  for (int i = 0; i < 2; ++i) offscreen.frame([&] { app.draw(snapshot); });
  const cv::Mat with = offscreen.read_rgba();
  snapshot.recording.state = RecordingStatus::State::Off;
  for (int i = 0; i < 2; ++i) offscreen.frame([&] { app.draw(snapshot); });
  const cv::Mat without = offscreen.read_rgba();
  const ScreenRect bar = app.layout().controls;
  EXPECT_GT(testing::count_colour(with, bar, colours::saturated, 25), 100);
  EXPECT_LT(testing::count_colour(without, bar, colours::saturated, 25), 10);
}

}  // namespace
}  // namespace nirslam::ui
