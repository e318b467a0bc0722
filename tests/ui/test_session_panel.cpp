// The Session tab, the notifications and the shortcut help rendered headless: the source picker
// hands the operator's choice to the app as a SOURCE string, a refusal shows in red in the panel,
// recent sources are listed, playback speed posts SetPacing, a worker failure appears in the
// window (not only on the console), and H lists every shortcut.

#include <memory>
#include <string>
#include <variant>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/capture/device_info.hpp"
#include "nirslam/capture/emulated_uvc.hpp"
#include "ui/application.hpp"
#include "ui/gl/shader.hpp"
#include "ui/panels/notification_area.hpp"
#include "ui/panels/session_panel.hpp"
#include "ui/panels/shortcut_help.hpp"
#include "ui/shortcuts.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using testing::full_window;

class SessionPanelTest : public testing::HeadlessGlTest {
protected:
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ui_ = std::make_unique<OffscreenUi>(1100, 320);
  }
  void TearDown() override {
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  void draw(const Snapshot& snapshot) {
    ui_->frame([&] { full_window([&] { panel_.draw(snapshot, sink_, actions_); }); });
  }
  // A full click (move, press, release) at the centre of `rect`.
  void click(const ScreenRect& rect, const Snapshot& snapshot) {
    testing::click_at(rect.centre(), [&] { draw(snapshot); });
  }
  cv::Mat shot(const char* name) {
    cv::Mat rgba = ui_->read_rgba();
    testing::save_if_requested(rgba, name);
    return rgba;
  }

  std::unique_ptr<OffscreenUi> ui_;
  SessionPanel panel_;
  std::vector<std::string> opened_;
  std::string refusal_;
  std::vector<Command> posted_;
  CommandSink sink_ = [this](Command c) { posted_.push_back(std::move(c)); };
  SessionActions actions_{[this](const std::string& source) {
                             opened_.push_back(source);
                             return refusal_;
                           },
                           // The emulated driver's cameras stand in for /dev/video* (no device here).
                           [](bool) {
                             EmulatedUvc emulator;
                             emulator.add_camera(emulated_mono_nir_camera("/dev/video0"));
                             emulator.add_camera(emulated_stereo_nir_camera("/dev/video2"));
                             return enumerate_devices(emulator);
                           },
                           {}};
};

TEST_F(SessionPanelTest, OpenHandsTheSimulatorChoiceToTheApp) {
  Snapshot snapshot;
  panel_.select("sim:parking@120W");
  EXPECT_EQ(panel_.chosen_source(), "sim:parking@120W");
  draw(snapshot);
  draw(snapshot);
  ASSERT_FALSE(panel_.open_button_rect().empty());
  click(panel_.open_button_rect(), snapshot);
  ASSERT_EQ(opened_.size(), 1u);
  EXPECT_EQ(opened_[0], "sim:parking@120W");
  EXPECT_TRUE(panel_.error().empty());
  // The opened source heads the recent list, which the panel draws.
  ASSERT_EQ(panel_.recent_sources.size(), 1u);
  EXPECT_EQ(panel_.recent_sources[0], "sim:parking@120W");
  const cv::Mat rgba = shot("SessionOpenSimulator");
  EXPECT_GT(testing::grey_stddev(rgba, panel_.recent_rect()), 3.0) << "the recent list has text";
}

TEST_F(SessionPanelTest, RefusalIsShownInRedAndIsNotRemembered) {
  Snapshot snapshot;
  panel_.select("/no/such/dataset");
  EXPECT_EQ(panel_.kind(), SessionPanel::SourceKind::Dataset);
  refusal_ = "/no/such/dataset: no such file or folder";
  draw(snapshot);
  click(panel_.open_button_rect(), snapshot);
  ASSERT_EQ(opened_.size(), 1u);
  EXPECT_EQ(opened_[0], "/no/such/dataset");
  EXPECT_EQ(panel_.error(), refusal_);
  EXPECT_TRUE(panel_.recent_sources.empty());
  const cv::Mat rgba = shot("SessionRefusal");
  ASSERT_FALSE(panel_.error_rect().empty());
  EXPECT_GT(testing::count_colour(rgba, panel_.error_rect(), colours::state_failed, 60), 20) << "red error text";
}

TEST_F(SessionPanelTest, EmptyFolderIsRefusedWithoutAskingTheApp) {
  Snapshot snapshot;
  panel_.select("");
  draw(snapshot);
  click(panel_.open_button_rect(), snapshot);
  EXPECT_TRUE(opened_.empty());
  EXPECT_NE(panel_.error().find("folder"), std::string::npos);
}

TEST_F(SessionPanelTest, RecentSourceReopensWithOneClick) {
  Snapshot snapshot;
  panel_.recent_sources = {"sim:room@20W", "/data/tunnel"};
  draw(snapshot);
  draw(snapshot);
  const ScreenRect list = panel_.recent_rect();
  ASSERT_GT(list.height(), 2.0f * ImGui::GetTextLineHeight());
  // The second row: one line below the first.
  const float row = ImGui::GetTextLineHeightWithSpacing();
  const ScreenRect second{ImVec2(list.min.x, list.min.y + row), ImVec2(list.max.x, list.min.y + 2.0f * row - 2.0f)};
  click(second, snapshot);
  ASSERT_EQ(opened_.size(), 1u);
  EXPECT_EQ(opened_[0], "/data/tunnel");
  EXPECT_EQ(panel_.recent_sources.front(), "/data/tunnel");
}

TEST_F(SessionPanelTest, CameraPickerOpensTheChosenDevice) {
  Snapshot snapshot;
  panel_.select("v4l2-emulated:/dev/video0");
  EXPECT_EQ(panel_.kind(), SessionPanel::SourceKind::Camera);
  draw(snapshot);
  draw(snapshot);
  ASSERT_FALSE(panel_.open_button_rect().empty()) << "the device list has an Open button";
  click(panel_.open_button_rect(), snapshot);
  ASSERT_EQ(opened_.size(), 1u);
  EXPECT_EQ(opened_[0].rfind("v4l2-emulated:/dev/video0", 0), 0u) << opened_[0];
  EXPECT_NE(opened_[0].find("format="), std::string::npos) << opened_[0];
  const cv::Mat rgba = shot("SessionCameraPicker");
  EXPECT_GT(testing::grey_stddev(rgba, ScreenRect{ImVec2(0, 0), ImVec2(500, 300)}), 8.0);
}

TEST_F(SessionPanelTest, SessionSourceStringsRoundTrip) {
  panel_.select("session:/media/usb/run-07");
  EXPECT_EQ(panel_.kind(), SessionPanel::SourceKind::Recording);
  EXPECT_EQ(panel_.chosen_source(), "session:/media/usb/run-07");
  panel_.select("sim:outdoor");
  EXPECT_EQ(panel_.chosen_source(), "sim:outdoor@50W");
}

class WindowExtrasTest : public testing::HeadlessGlTest {};

TEST_F(WindowExtrasTest, WorkerFailureIsShownInTheWindowUntilDismissed) {
  OffscreenUi offscreen(1280, 800);
  Application app(gl::find_shader_dir(), {});
  Snapshot snapshot;
  snapshot.sequence = 1;
  snapshot.state = WorkerState::Running;
  offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_EQ(app.notifications().size(), 0u);
  snapshot.sequence = 2;
  snapshot.state = WorkerState::Failed;
  snapshot.message = "camera /dev/video2 disappeared (ENODEV): 1234 frames kept";
  for (int i = 0; i < 3; ++i) offscreen.frame([&] { app.draw(snapshot); });
  ASSERT_EQ(app.notifications().size(), 1u);
  const ScreenRect box = app.notifications().drawn_rect();
  ASSERT_FALSE(box.empty());
  const cv::Mat rgba = offscreen.read_rgba();
  testing::save_if_requested(rgba, "NotificationError");
  EXPECT_GT(testing::count_colour(rgba, box, colours::state_failed, 40), 30) << "red border and label";
  EXPECT_GT(testing::grey_stddev(rgba, box), 8.0) << "the message is written";
  // Errors do not fade; a notice does.
  for (int i = 0; i < 3; ++i) offscreen.frame([&] { app.draw(snapshot); }, 4.0);
  EXPECT_EQ(app.notifications().size(), 1u);
  app.notifications().push(NotificationArea::Severity::Notice, "export finished");
  EXPECT_EQ(app.notifications().size(), 2u);
  for (int i = 0; i < 3; ++i) offscreen.frame([&] { app.draw(snapshot); }, 4.0);
  EXPECT_EQ(app.notifications().size(), 1u);
}

TEST_F(WindowExtrasTest, ShortcutsSwitchViewsAndHelpListsThemAll) {
  OffscreenUi offscreen(1280, 800);
  Application app(gl::find_shader_dir(), {});
  Snapshot snapshot;
  offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_EQ(app.current_tab(), Application::StripTab::Illumination);
  ImGui::GetIO().AddInputCharacter('o');
  offscreen.frame([&] { app.draw(snapshot); });
  offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_EQ(app.current_tab(), Application::StripTab::Session);
  ImGui::GetIO().AddInputCharacter('P');
  offscreen.frame([&] { app.draw(snapshot); });
  offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_EQ(app.current_tab(), Application::StripTab::Photometric);
  const bool corrected = app.feed().show_corrected;
  ImGui::GetIO().AddInputCharacter('c');
  offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_NE(app.feed().show_corrected, corrected);
  ImGui::GetIO().AddInputCharacter('w');
  offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_TRUE(app.view3d().follow);

  ImGui::GetIO().AddInputCharacter('?');
  for (int i = 0; i < 3; ++i) offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_TRUE(app.shortcut_help().visible);
  const ScreenRect help = app.shortcut_help().drawn_rect();
  ASSERT_FALSE(help.empty());
  // One table row per shortcut: the box is at least that tall.
  EXPECT_GT(help.height(), static_cast<float>(shortcuts().size()) * ImGui::GetTextLineHeight());
  const cv::Mat rgba = offscreen.read_rgba();
  testing::save_if_requested(rgba, "ShortcutHelp");
  EXPECT_GT(testing::count_colour(rgba, help, colours::accent, 40), 50) << "key labels in the accent colour";
  ImGui::GetIO().AddInputCharacter('h');
  offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_FALSE(app.shortcut_help().visible);
}

// Camera controls whose state the test sets: stands in for a V4L2 source's.
class ScriptedCamera final : public CameraControls {
public:
  CameraState current;
  CameraState state() const override { return current; }
  void set_exposure_ms(double) override {}
  void set_gain(double) override {}
  void set_auto_exposure(bool) override {}
  void set_frame_rate(double) override {}
  void set_locked(bool) override {}
};

TEST_F(WindowExtrasTest, CameraUnplugIsShownInTheWindowAndTheCameraTabDrawsItsControls) {
  OffscreenUi offscreen(1280, 800);
  Application app(gl::find_shader_dir(), {});
  auto camera = std::make_shared<ScriptedCamera>();
  camera->current.device = "/dev/video0";
  camera->current.connection = CameraConnection::Streaming;
  camera->current.frames_captured = 480;
  SessionActions actions;
  actions.camera_controls = [camera] { return camera; };
  app.set_session_actions(actions);
  app.select_tab(Application::StripTab::Camera);
  Snapshot snapshot;
  for (int i = 0; i < 2; ++i) offscreen.frame([&] { app.draw(snapshot); });
  EXPECT_EQ(app.current_tab(), Application::StripTab::Camera);
  EXPECT_EQ(app.notifications().size(), 0u);
  EXPECT_FALSE(app.camera().banner_rect().empty()) << "the camera panel is drawn in its tab";
  camera->current.connection = CameraConnection::Unplugged;
  camera->current.message = "ENODEV while dequeuing";
  for (int i = 0; i < 2; ++i) offscreen.frame([&] { app.draw(snapshot); });
  ASSERT_EQ(app.notifications().size(), 1u);
  const cv::Mat rgba = offscreen.read_rgba();
  testing::save_if_requested(rgba, "CameraUnplugged");
  EXPECT_GT(testing::count_colour(rgba, app.notifications().drawn_rect(), colours::banner_dark, 40), 20);
}

TEST(Shortcuts, EveryKeyIsUniqueAndCaseInsensitive) {
  for (const Shortcut& a : shortcuts()) {
    EXPECT_EQ(shortcut_for(static_cast<unsigned char>(a.key)), &a);
    if (a.key >= 'a' && a.key <= 'z') {
      EXPECT_EQ(shortcut_for(static_cast<unsigned>(a.key - 'a' + 'A')), &a);
    }
    for (const Shortcut& b : shortcuts())
      if (&a != &b) {
        EXPECT_NE(a.key, b.key);
      }
  }
  EXPECT_EQ(shortcut_for('?')->id, ShortcutAction::Help);
  EXPECT_EQ(shortcut_for('z'), nullptr);
}

TEST_F(WindowExtrasTest, PreferencesRoundTripThroughTheApplication) {
  OffscreenUi offscreen(1280, 800);
  std::vector<Command> posted;
  Application app(gl::find_shader_dir(), [&posted](Command c) { posted.push_back(std::move(c)); });
  UiPreferences in;
  in.feed_corrected = true;
  in.view3d_follow = true;
  in.view3d_colour_by_error = false;
  in.recent_sources = {"sim:room@20W"};
  in.last_source = "sim:room@20W";
  in.strip_tab = "session";
  in.chosen_pipeline_mode = "odometry";
  in.recorded_speed = false;
  app.apply(in);
  Snapshot snapshot;
  offscreen.frame([&] { app.draw(snapshot); });
  offscreen.frame([&] { app.draw(snapshot); });
  UiPreferences out;
  app.capture(out);
  EXPECT_TRUE(out.feed_corrected);
  EXPECT_TRUE(out.view3d_follow);
  EXPECT_FALSE(out.view3d_colour_by_error);
  EXPECT_EQ(out.recent_sources, in.recent_sources);
  EXPECT_EQ(out.strip_tab, "session");
  EXPECT_FALSE(out.recorded_speed);
  EXPECT_EQ(out.chosen_pipeline_mode, "odometry") << "the operator's mode is kept for next time";
  EXPECT_EQ(app.session().chosen_source(), "sim:room@20W");
  // The saved mode and pacing reach the worker.
  bool mode = false;
  bool pacing = false;
  for (const Command& c : posted) {
    if (const auto* m = std::get_if<command::SetPipelineMode>(&c)) mode = m->mode == PipelineMode::Odometry;
    if (const auto* p = std::get_if<command::SetPacing>(&c)) pacing = p->pacing == Pacing::AsFastAsPossible;
  }
  EXPECT_TRUE(mode);
  EXPECT_TRUE(pacing);
}

// No mode picked yet: nothing overrides the config's mode (the automatic one by default); "auto"
// picked before asks for it again.
TEST_F(WindowExtrasTest, OnlyAModeTheOperatorPickedIsPosted) {
  OffscreenUi offscreen(1280, 800);
  std::vector<Command> posted;
  Application app(gl::find_shader_dir(), [&posted](Command c) { posted.push_back(std::move(c)); });
  app.apply(UiPreferences{});
  for (const Command& c : posted) EXPECT_FALSE(std::holds_alternative<command::SetPipelineMode>(c));
  UiPreferences out;
  app.capture(out);
  EXPECT_TRUE(out.chosen_pipeline_mode.empty());

  posted.clear();
  UiPreferences automatic;
  automatic.chosen_pipeline_mode = "auto";
  app.apply(automatic);
  int automatic_posts = 0;
  for (const Command& c : posted)
    if (const auto* m = std::get_if<command::SetPipelineMode>(&c)) automatic_posts += m->mode ? 0 : 1;
  EXPECT_EQ(automatic_posts, 1);
}

}  // namespace
}  // namespace nirslam::ui
