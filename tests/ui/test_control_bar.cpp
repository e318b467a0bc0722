// The control bar's seek bar: drawn with a knob for a source that can jump, a click or a drag
// posts command::Seek for the frame under the mouse on release, and nothing is posted for a
// source that cannot jump or while a recording runs.

#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <imgui.h>

#include "ui/panels/control_bar.hpp"
#include "ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using testing::full_window;

Snapshot replaying(std::int64_t index, std::size_t total, bool seekable) {
  Snapshot s;
  s.state = WorkerState::Paused;
  s.source.kind = "session";
  s.source.description = "sessions/tunnel-run-3";
  s.source.frame_count = total;
  s.source.seekable = seekable;
  s.frames_processed = index + 1;
  Frame frame;
  frame.image = cv::Mat(8, 8, CV_8UC1, cv::Scalar(0));
  frame.index = index;
  s.frame = frame;
  return s;
}

class ControlBarTest : public testing::HeadlessGlTest {
protected:
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ui_ = std::make_unique<OffscreenUi>(1280, 60);
  }
  void TearDown() override {
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  cv::Mat draw(const Snapshot& snapshot) {
    ui_->frame([&] { full_window([&] { bar_.draw(snapshot, sink_); }); });
    return ui_->read_rgba();
  }
  // Press at `from`, move to `to` (a frame each), release there.
  void drag(ImVec2 from, ImVec2 to, const Snapshot& snapshot) {
    ImGuiIO& io = ImGui::GetIO();
    io.MousePos = from;
    draw(snapshot);
    io.MouseDown[0] = true;
    draw(snapshot);
    io.MousePos = to;
    draw(snapshot);
    dragging_shot_ = draw(snapshot);
    io.MouseDown[0] = false;
    draw(snapshot);
    io.MousePos = ImVec2(-1.0f, -1.0f);
    draw(snapshot);
  }
  ImVec2 at_fraction(double f) const {
    const ScreenRect& r = bar_.progress_rect();
    return ImVec2(r.min.x + static_cast<float>(f) * r.width(), r.centre().y);
  }
  std::vector<std::size_t> seeks() const {
    std::vector<std::size_t> out;
    for (const Command& c : posted_)
      if (const auto* seek = std::get_if<command::Seek>(&c)) out.push_back(seek->position);
    return out;
  }

  std::unique_ptr<OffscreenUi> ui_;
  ControlBar bar_;
  std::vector<Command> posted_;
  CommandSink sink_ = [this](Command c) { posted_.push_back(std::move(c)); };
  cv::Mat dragging_shot_;
};

// Pixels of `colour` in the columns of `rect` between fractions a and b of its width.
int colour_in(const cv::Mat& shot, const ScreenRect& rect, double a, double b, ImU32 colour) {
  ScreenRect part = rect;
  part.min.x = rect.min.x + static_cast<float>(a) * rect.width();
  part.max.x = rect.min.x + static_cast<float>(b) * rect.width();
  return testing::count_colour(shot, part, colour, 20);
}

TEST_F(ControlBarTest, SeekableSourceShowsAKnobAtItsPosition) {
  draw(replaying(119, 300, true));
  const cv::Mat shot = draw(replaying(119, 300, true));
  testing::save_if_requested(shot, "ControlBarSeekable");
  const ScreenRect& rect = bar_.progress_rect();
  ASSERT_FALSE(rect.empty());
  // Frame 120 of 300: filled to 40 %, the knob there, the rest unfilled.
  EXPECT_GT(colour_in(shot, rect, 0.02, 0.35, colours::accent), 20);
  EXPECT_EQ(colour_in(shot, rect, 0.45, 0.98, colours::accent), 0);
  EXPECT_GT(colour_in(shot, rect, 0.34, 0.46, colours::text), 15) << "the knob";
  EXPECT_EQ(colour_in(shot, rect, 0.6, 1.0, colours::text), 0);

  const cv::Mat plain = draw(replaying(119, 300, false));
  EXPECT_EQ(colour_in(plain, bar_.progress_rect(), 0.0, 1.0, colours::text), 0) << "no knob where the source cannot jump";
  EXPECT_GT(colour_in(plain, bar_.progress_rect(), 0.02, 0.35, colours::accent), 20) << "still the progress";
}

TEST_F(ControlBarTest, ClickAndDragPostTheFrameUnderTheMouseOnRelease) {
  const Snapshot snapshot = replaying(10, 300, true);
  draw(snapshot);
  drag(at_fraction(0.75), at_fraction(0.75), snapshot);
  ASSERT_EQ(seeks(), std::vector<std::size_t>({224})) << "frame 225 of 300 sits at 75 %";

  posted_.clear();
  drag(at_fraction(0.2), at_fraction(0.5), snapshot);
  ASSERT_EQ(seeks(), std::vector<std::size_t>({149})) << "one jump, to where the drag ended";
  // While dragging, the bar already shows the target (filled to 50 %), not the current frame.
  EXPECT_GT(colour_in(dragging_shot_, bar_.progress_rect(), 0.3, 0.48, colours::accent), 20);

  posted_.clear();
  drag(at_fraction(-0.5), at_fraction(-0.5), snapshot);  // left of the bar: nothing
  EXPECT_TRUE(seeks().empty());
}

TEST_F(ControlBarTest, NoJumpForALiveSourceOrWhileRecording) {
  Snapshot live = replaying(10, 300, false);
  draw(live);
  drag(at_fraction(0.5), at_fraction(0.5), live);
  EXPECT_TRUE(seeks().empty());

  Snapshot recording = replaying(10, 300, true);
  recording.recording.state = RecordingStatus::State::Recording;
  draw(recording);
  drag(at_fraction(0.5), at_fraction(0.5), recording);
  EXPECT_TRUE(seeks().empty());
  const cv::Mat shot = draw(recording);
  EXPECT_EQ(colour_in(shot, bar_.progress_rect(), 0.0, 1.0, colours::text), 0) << "no knob while recording";
}

// The mode combo: "automatic" is its first entry; picking it asks the worker to choose per
// source and is remembered as the operator's choice; picking it again while it runs posts nothing.
TEST_F(ControlBarTest, AutomaticModeIsTheComboFirstEntry) {
  ui_.reset();  // room below the bar for the open list
  ui_ = std::make_unique<OffscreenUi>(1280, 400);
  Snapshot snapshot = replaying(10, 300, true);
  snapshot.pipeline_mode = "calibrated";
  const auto pick_first_entry = [&](const char* shot_name) {
    const auto frame = [&] { draw(snapshot); };
    frame();
    const ScreenRect combo = bar_.mode_rect();
    testing::click_at(combo.centre(), frame);
    // The list opens under the combo; its first row is "automatic".
    const ImVec2 first_row(combo.min.x + 20.0f,
                           combo.max.y + ImGui::GetStyle().WindowPadding.y + 0.5f * ImGui::GetTextLineHeight() + 2.0f);
    ImGui::GetIO().MousePos = first_row;
    testing::save_if_requested(draw(snapshot), shot_name);
    testing::click_at(first_row, frame);
  };
  const auto automatic_posts = [&] {
    int n = 0;
    for (const Command& c : posted_)
      if (const auto* m = std::get_if<command::SetPipelineMode>(&c)) n += m->mode ? 100 : 1;
    return n;
  };
  EXPECT_TRUE(bar_.chosen_pipeline_mode.empty());
  pick_first_entry("ControlBarModeList");
  EXPECT_EQ(automatic_posts(), 1);
  EXPECT_EQ(bar_.chosen_pipeline_mode, "auto");

  posted_.clear();
  snapshot.pipeline_mode = "illuminated";
  snapshot.pipeline_mode_automatic = true;
  const cv::Mat shot = draw(snapshot);
  testing::save_if_requested(shot, "ControlBarAutomaticMode");
  pick_first_entry("ControlBarModeListAutomatic");
  EXPECT_EQ(automatic_posts(), 0) << "already automatic";
}

}  // namespace
}  // namespace nirslam::ui
