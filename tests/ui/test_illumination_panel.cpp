// The illumination panel rendered headless: the warning banner's colour follows the frame's
// verdict, the fitted curve lies where the fit puts it, the recommended point is marked on it, the
// measured points are drawn; a sweep recorded by the worker on the demo's lamp, end to end; the
// camera's auto exposure held by the window while the wizard sweeps, and given back after.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>
#include <variant>
#include <vector>

#include <gtest/gtest.h>

#include "core/test_v4l2_fixtures.hpp"
#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/config/illumination_config.hpp"
#include "nirslam/illumination/sweep_recorder.hpp"
#include "nirslam/photometric/exposure_sweep_calibration.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/demo_source.hpp"
#include "nirslam/worker/worker.hpp"
#include "ui/application.hpp"
#include "ui/gl/shader.hpp"
#include "ui/panels/illumination_panel.hpp"
#include "ui/ui_test_support.hpp"
#include "worker/still_rig_sweep.hpp"

namespace nirslam::ui {
namespace {

using namespace std::chrono_literals;
using testing::full_window;
using testing::near;
using testing::pixel;

IlluminationConfig shipped_config() {
  return load_illumination_config(std::filesystem::path(NIRSLAM_SOURCE_DIR) / "config/illumination.yaml");
}

// A frame with texture; `saturated` of its rows at 255, or all of it dark.
Frame textured_frame(double saturated_rows, bool dark) {
  Frame frame;
  frame.image = cv::Mat(240, 320, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(frame.image, cv::RNG::UNIFORM, dark ? 0 : 40, dark ? 12 : 220);
  frame.image.rowRange(0, static_cast<int>(saturated_rows * 240)).setTo(255);
  frame.index = 41;
  frame.illuminator_power_w = 70.0;
  return frame;
}

// What the worker publishes for `frame`, with the illumination status `status`.
Snapshot snapshot_of(Frame frame, std::shared_ptr<const IlluminationStatus> status, const ExposureLimits& limits) {
  Snapshot s = testing::snapshot_with_frame(frame);
  QualityMeter meter;
  const FrameMetrics m = meter.measure(frame, &s.histogram, &s.feature_grid);
  s.quality = m.quality;
  s.structure = m.structure;
  s.exposure = check_exposure(m.quality, limits);
  s.illuminator_power_w = frame.illuminator_power_w;
  s.illumination = std::move(status);
  return s;
}

const SaturationCurve kCurve{2.2, 7.3, 24.0};

// A sweep of the room at the plan's powers, 10 frames each, entropy on kCurve with a little scatter.
std::shared_ptr<const IlluminationStatus> swept_status() {
  SweepRecorder recorder(shipped_config());
  recorder.apply(sweep_command::Start{{}, 10});
  const std::vector<double> powers = recorder.status()->plan.powers_w;  // a copy: the status is replaced
  for (const double power : powers) {
    recorder.apply(sweep_command::Capture{power});
    for (int i = 0; i < 10; ++i) {
      FrameMetrics m;
      m.quality.entropy_bits = kCurve(power) + 0.02 * std::sin(1.7 * i + power);
      m.quality.saturated_fraction = std::max(0.0, (power - 100.0) * 0.0004);
      recorder.add_frame(m, power, true);
    }
  }
  return recorder.status();
}

class IlluminationPanelTest : public testing::HeadlessGlTest {
protected:
  cv::Mat render(int width, int height, IlluminationPanel& panel, const Snapshot& snapshot, const char* name = nullptr) {
    ui_.reset();  // one ImGui context at a time
    ui_ = std::make_unique<OffscreenUi>(width, height);
    for (int i = 0; i < 2; ++i) ui_->frame([&] { full_window([&] { panel.draw(snapshot, {}); }); });
    cv::Mat shot = ui_->read_rgba();
    testing::save_if_requested(shot, name ? name : ::testing::UnitTest::GetInstance()->current_test_info()->name());
    return shot;
  }
  void TearDown() override {
    ui_.reset();
    HeadlessGlTest::TearDown();
  }

  // The screen position of (power, entropy) in the plot (x from 0 to the lamp's 150 W, y 0..8 bits).
  static ImVec2 at(const ScreenRect& plot, double power_w, double bits) {
    return ImVec2(plot.min.x + static_cast<float>(power_w / 150.0) * plot.width(),
                  plot.max.y - static_cast<float>(bits / 8.0) * plot.height());
  }

  std::unique_ptr<OffscreenUi> ui_;
};

TEST_F(IlluminationPanelTest, ClippedFrameShowsARedBannerAndTheSweepCurveWithTheRecommendedPoint) {
  const auto status = swept_status();
  const Recommendation& rec = status->recommendation;
  ASSERT_EQ(rec.source, RecommendationSource::Sweep);
  ASSERT_TRUE(rec.fit);
  const IlluminationConfig config = shipped_config();
  const Snapshot snapshot = snapshot_of(textured_frame(0.2, false), status, config.exposure);
  ASSERT_EQ(snapshot.exposure.verdict, ExposureVerdict::Clipped);

  for (const ImVec2 size : {ImVec2(900, 300), ImVec2(460, 660)}) {  // the strip under the feed; a column
    SCOPED_TRACE(size.x);
    IlluminationPanel panel;
    const cv::Mat shot = render(static_cast<int>(size.x), static_cast<int>(size.y), panel, snapshot,
                                size.x > 800 ? "ClippedFrameWide" : "ClippedFrameNarrow");

    // The banner is red where the text is not.
    const ScreenRect& banner = panel.banner_rect();
    ASSERT_GT(banner.width(), 300.0f);
    EXPECT_TRUE(near(pixel(shot, ImVec2(banner.max.x - 5.0f, banner.centre().y)), colours::banner_clipped, 3))
        << pixel(shot, ImVec2(banner.max.x - 5.0f, banner.centre().y));
    EXPECT_GT(testing::count_colour(shot, banner, colours::banner_clipped, 3), static_cast<int>(0.5f * banner.width() * banner.height()));

    // The fitted curve runs across the plot at the fit's heights.
    const ScreenRect& plot = panel.plot_rect();
    ASSERT_GT(plot.width(), 250.0f);
    ASSERT_GT(plot.height(), 100.0f);
    EXPECT_GT(testing::count_colour(shot, plot, colours::fit_curve, 30), static_cast<int>(plot.width()));
    for (const double power : {10.0, 35.0, 140.0}) {
      const ImVec2 expected = at(plot, power, rec.fit->curve(power));
      const int x = static_cast<int>(expected.x);
      int found = -1;
      for (int y = static_cast<int>(plot.min.y); y < static_cast<int>(plot.max.y) && found < 0; ++y)
        if (near(pixel(shot, x, y), colours::fit_curve, 30)) found = y;
      EXPECT_NEAR(found, expected.y, 3.0f) << "curve at " << power << " W";
    }

    // The recommended point: a marker in its colour on the curve at the recommended power.
    ASSERT_TRUE(panel.recommended_marker());
    const ImVec2 marker = *panel.recommended_marker();
    const ImVec2 expected = at(plot, rec.power_w, rec.expected_entropy_bits);
    EXPECT_NEAR(marker.x, expected.x, 1.0f);
    EXPECT_NEAR(marker.y, expected.y, 1.0f);
    EXPECT_TRUE(near(pixel(shot, marker), colours::recommended, 3)) << pixel(shot, marker);
    ScreenRect around{ImVec2(marker.x - 8, marker.y - 8), ImVec2(marker.x + 8, marker.y + 8)};
    EXPECT_GT(testing::count_colour(shot, around, colours::recommended, 3), 60);

    // A measured point (20 W) in the point colour.
    const ImVec2 point = at(plot, 20.0, status->points[1].entropy_bits.mean);
    EXPECT_TRUE(near(pixel(shot, point), colours::sweep_point, 10)) << pixel(shot, point);
  }
}

TEST_F(IlluminationPanelTest, BannerIsAmberForADarkFrameAndGreenForAGoodOne) {
  const IlluminationConfig config = shipped_config();
  const auto status = SweepRecorder(config).status();
  IlluminationPanel panel;
  {
    const Snapshot dark = snapshot_of(textured_frame(0.0, true), status, config.exposure);
    ASSERT_EQ(dark.exposure.verdict, ExposureVerdict::Dark);
    const cv::Mat shot = render(900, 300, panel, dark);
    const ScreenRect& banner = panel.banner_rect();
    EXPECT_TRUE(near(pixel(shot, ImVec2(banner.max.x - 5.0f, banner.centre().y)), colours::banner_dark, 3));
  }
  {
    const Snapshot good = snapshot_of(textured_frame(0.0, false), status, config.exposure);
    ASSERT_EQ(good.exposure.verdict, ExposureVerdict::Ok) << good.exposure.message;
    const cv::Mat shot = render(900, 300, panel, good);
    const ScreenRect& banner = panel.banner_rect();
    EXPECT_TRUE(near(pixel(shot, ImVec2(banner.max.x - 5.0f, banner.centre().y)), colours::banner_ok, 3));
    // No sweep yet: the room's prior, no fitted curve, the marker at the prior's centre on the axis.
    EXPECT_EQ(testing::count_colour(shot, panel.plot_rect(), colours::fit_curve, 20), 0);
    ASSERT_TRUE(panel.recommended_marker());
    EXPECT_NEAR(panel.recommended_marker()->x, at(panel.plot_rect(), 75.0, 0.0).x, 1.0f);
    EXPECT_TRUE(near(pixel(shot, *panel.recommended_marker()), colours::recommended, 3));
    // The coverage map shows the frame's corners.
    EXPECT_GT(good.structure.feature_count, 50);
    EXPECT_GT(testing::grey_stddev(shot, panel.coverage_map_rect()), 5.0);
  }
}

TEST_F(IlluminationPanelTest, EmptySnapshotDrawsWithoutAdvisorState) {
  IlluminationPanel panel;
  const cv::Mat shot = render(900, 300, panel, Snapshot{});
  EXPECT_FALSE(panel.banner_rect().empty());
  EXPECT_TRUE(near(pixel(shot, ImVec2(panel.banner_rect().max.x - 5.0f, panel.banner_rect().centre().y)),
                   colours::frame_bg, 3));
  EXPECT_TRUE(panel.plot_rect().empty());
  EXPECT_FALSE(panel.recommended_marker());
}

// The wizard asks for the plan's next power; a click on Capture posts it to the worker.
TEST_F(IlluminationPanelTest, CaptureButtonPostsTheRequestedPower) {
  SweepRecorder recorder(shipped_config());
  recorder.apply(sweep_command::Start{});
  recorder.apply(sweep_command::Capture{0.0});
  for (int i = 0; i < 30; ++i) recorder.add_frame(FrameMetrics{}, 0.0, true);
  ASSERT_EQ(recorder.status()->requested_power_w(), 20.0);
  Snapshot snapshot = snapshot_of(textured_frame(0.0, false), recorder.status(), shipped_config().exposure);
  snapshot.state = WorkerState::Running;

  std::vector<Command> posted;
  const CommandSink sink = [&posted](Command c) { posted.push_back(std::move(c)); };
  IlluminationPanel panel;
  ui_.reset();
  ui_ = std::make_unique<OffscreenUi>(900, 300);
  ui_->frame([&] { full_window([&] { panel.draw(snapshot, sink); }); });
  const ScreenRect button = panel.capture_button_rect();
  ASSERT_FALSE(button.empty());
  ImGuiIO& io = ImGui::GetIO();
  io.MousePos = button.centre();
  ui_->frame([&] { full_window([&] { panel.draw(snapshot, sink); }); });
  io.MouseDown[0] = true;
  ui_->frame([&] { full_window([&] { panel.draw(snapshot, sink); }); });
  io.MouseDown[0] = false;
  ui_->frame([&] { full_window([&] { panel.draw(snapshot, sink); }); });
  io.MousePos = ImVec2(-1.0f, -1.0f);
  testing::save_if_requested(ui_->read_rgba(), "CaptureButtonPostsTheRequestedPower");

  ASSERT_EQ(posted.size(), 1u);
  const auto* sweep = std::get_if<command::Sweep>(&posted[0]);
  ASSERT_NE(sweep, nullptr);
  const auto* capture = std::get_if<sweep_command::Capture>(&sweep->action);
  ASSERT_NE(capture, nullptr);
  EXPECT_DOUBLE_EQ(capture->power_w, 20.0);
}

// End to end: the worker's wizard sweeps the demo's lamp; the panel draws what it recorded.
TEST_F(IlluminationPanelTest, DrawsASweepRecordedByTheWorkerOnTheDemo) {
  WorkerOptions options{.pacing = Pacing::AsFastAsPossible, .loop = true};
  options.illumination = shipped_config();
  options.illumination.sweep.settle_frames = 1;
  Worker worker(options);
  worker.post(command::SetSource{[] { return make_demo_source(); }});
  worker.post(command::Sweep{sweep_command::Start{{0, 10, 20, 30, 40, 50, 70, 100}, 5}});
  worker.post(command::Start{});
  for (int step = 0; step < 8; ++step) {
    const auto asked = worker.wait_for(
        [](const Snapshot& s) { return s.illumination && s.illumination->requested_power_w().has_value(); }, 20s);
    ASSERT_TRUE(asked->illumination && asked->illumination->requested_power_w()) << asked->message;
    const double power = *asked->illumination->requested_power_w();
    worker.post(command::Sweep{sweep_command::Capture{power}});
    const auto captured = worker.wait_for(
        [&](const Snapshot& s) {
          return s.illumination && s.illumination->progress.stage != SweepStage::Capturing &&
                 std::any_of(s.illumination->points.begin(), s.illumination->points.end(),
                             [&](const SweepPoint& p) { return p.power_w == power && p.frames == 5; });
        },
        20s);
    ASSERT_NE(captured->illumination->progress.stage, SweepStage::Capturing) << power << " W";
  }
  const auto done = worker.wait_for(
      [](const Snapshot& s) { return s.illumination && s.illumination->progress.stage == SweepStage::Complete; }, 20s);
  ASSERT_EQ(done->illumination->progress.stage, SweepStage::Complete);
  // Show the frame at the recommended power, as an operator would after the sweep.
  const double recommended = done->illumination->recommendation.power_w;
  worker.post(command::SetIlluminatorPower{recommended});
  const auto shown = worker.wait_for(
      [&](const Snapshot& s) { return s.frame && s.frame->illuminator_power_w == recommended; }, 20s);
  worker.post(command::Pause{});
  ASSERT_EQ(shown->illumination->points.size(), 8u);
  ASSERT_EQ(shown->illumination->recommendation.source, RecommendationSource::Sweep)
      << shown->illumination->recommendation.reasons.front();

  IlluminationPanel panel;
  const cv::Mat shot = render(900, 290, panel, *shown, "illumination-panel");
  EXPECT_GT(testing::count_colour(shot, panel.plot_rect(), colours::fit_curve, 30), static_cast<int>(panel.plot_rect().width()));
  ASSERT_TRUE(panel.recommended_marker());
  EXPECT_TRUE(near(pixel(shot, *panel.recommended_marker()), colours::recommended, 3));
  EXPECT_LT(shown->quality.saturated_fraction, 0.02) << "the recommended power respects the clipping limit";
}

// After a sweep of the simulated room (tripod, exposure locked) the panel shows the camera
// response the worker fitted from the sweep's frames; Hold posts the folder to write it into, and
// once the worker holds it the row says so.
TEST_F(IlluminationPanelTest, ShowsTheSweepsCameraResponseAndHoldsIt) {
  WorkerOptions options{.pacing = Pacing::AsFastAsPossible, .loop = true};
  options.pipeline.mode = PipelineMode::Quality;
  options.illumination = shipped_config();
  options.illumination.sweep.settle_frames = 1;
  Worker worker(options);
  const SimulatorOptions sim = nirslam::testing::still_rig();
  worker.post(command::SetSource{[sim] { return make_simulated_source(sim); }});
  worker.post(command::Start{});
  nirslam::testing::sweep_through(worker, {0, 10, 20, 40, 70, 100, 150}, 2);
  if (HasFatalFailure()) return;
  const auto fitted = worker.wait_for(
      [](const Snapshot& s) { return s.sweep_response && s.sweep_response->state == SweepResponse::State::Done; }, 60s);
  worker.post(command::Pause{});
  ASSERT_TRUE(fitted->sweep_response && fitted->sweep_response->state == SweepResponse::State::Done) << fitted->message;

  const auto root = std::filesystem::temp_directory_path() / "nirslam_ui_sweep_response";
  std::filesystem::remove_all(root);
  std::vector<Command> posted;
  const CommandSink sink = [&posted](Command c) { posted.push_back(std::move(c)); };
  IlluminationPanel panel;
  panel.set_response_root(root);
  ui_.reset();
  ui_ = std::make_unique<OffscreenUi>(900, 290);
  const auto draw = [&](const Snapshot& snapshot) { ui_->frame([&] { full_window([&] { panel.draw(snapshot, sink); }); }); };
  draw(*fitted);
  draw(*fitted);
  const cv::Mat shot = ui_->read_rgba();
  testing::save_if_requested(shot, "illumination-panel-response");
  ASSERT_FALSE(panel.response_curve_rect().empty());
  EXPECT_GT(testing::count_colour(shot, panel.response_curve_rect(), colours::estimate, 30),
            static_cast<int>(panel.response_curve_rect().width() / 2))
      << "the fitted curve is drawn";
  const ScreenRect hold = panel.hold_button_rect();
  ASSERT_FALSE(hold.empty());
  ImGuiIO& io = ImGui::GetIO();
  io.MousePos = hold.centre();
  draw(*fitted);
  io.MouseDown[0] = true;
  draw(*fitted);
  io.MouseDown[0] = false;
  draw(*fitted);
  io.MousePos = ImVec2(-1.0f, -1.0f);
  ASSERT_EQ(posted.size(), 1u);
  const auto* command = std::get_if<command::HoldSweepResponse>(&posted[0]);
  ASSERT_NE(command, nullptr);
  EXPECT_EQ(command->folder.parent_path(), root);
  EXPECT_EQ(command->folder.filename().string().rfind("response-", 0), 0u) << command->folder;

  worker.post(*command);
  const auto held = worker.wait_for([](const Snapshot& s) { return s.sweep_response && s.sweep_response->held; }, 20s);
  ASSERT_TRUE(held->sweep_response && held->sweep_response->held) << held->message;
  EXPECT_TRUE(std::filesystem::exists(command->folder / "pcalib.txt"));
  draw(*held);
  draw(*held);
  const cv::Mat held_shot = ui_->read_rgba();
  testing::save_if_requested(held_shot, "illumination-panel-response-held");
  EXPECT_GT(testing::count_colour(held_shot, panel.hold_button_rect(), colours::recommended, 40), 20) << "the held badge";
  std::filesystem::remove_all(root);
}

// The window holds a live camera's exposure while the wizard sweeps (the worker's wizard, the
// GUI's camera controls): locked when the sweep starts, shown under the wizard, given back after.
TEST_F(IlluminationPanelTest, TheWindowLocksTheCamerasAutoExposureWhileTheWizardSweeps) {
  EmulatedCameraSpec camera = nirslam::testing::small_camera();
  auto emulator = nirslam::testing::emulator_with(camera);
  emulator->limit_frames("/dev/video0", 0);
  V4l2SourceSpec spec;
  spec.format = PixelFormat::Grey;
  spec.width = 64;
  spec.height = 48;
  spec.auto_exposure = true;
  const auto source = open_v4l2_source(spec, emulator);
  const std::shared_ptr<CameraControls> controls = source->controls();

  ui_.reset();
  ui_ = std::make_unique<OffscreenUi>(1280, 800);
  Application app(gl::find_shader_dir(), [](Command) {});
  SessionActions actions;
  actions.camera_controls = [controls] { return controls; };
  app.set_session_actions(actions);
  app.select_tab(Application::StripTab::Illumination);

  SweepRecorder recorder(shipped_config());
  recorder.apply(sweep_command::Start{});
  Snapshot sweeping = snapshot_of(textured_frame(0.0, false), recorder.status(), shipped_config().exposure);
  sweeping.state = WorkerState::Running;
  const auto wait_for = [&](const Snapshot& snapshot, auto done) {
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    do {
      ui_->frame([&] { app.draw(snapshot); });
      if (done(controls->state())) return true;
      std::this_thread::sleep_for(1ms);
    } while (std::chrono::steady_clock::now() < deadline);
    return false;
  };
  ASSERT_TRUE(wait_for(sweeping, [](const CameraState& s) { return s.locked && !s.auto_exposure; }));
  emulator->allow_frames("/dev/video0", 1);  // a frame says what the exposure is held at
  ASSERT_TRUE(source->next().has_value());
  ui_->frame([&] { app.draw(sweeping); });
  const cv::Mat shot = ui_->read_rgba();
  testing::save_if_requested(shot, "WindowLocksTheCameraForTheSweep");
  EXPECT_EQ(app.notifications().size(), 1u) << "the lock is announced";
  const ScreenRect hold = app.illumination().camera_hold_rect();
  ASSERT_FALSE(hold.empty()) << "the wizard says what the camera is held at";
  EXPECT_GT(testing::count_colour(shot, hold, colours::text_dim, 40), 30);

  recorder.apply(sweep_command::Finish{});
  Snapshot finished = sweeping;
  finished.illumination = recorder.status();
  ASSERT_TRUE(wait_for(finished, [](const CameraState& s) { return !s.locked && s.auto_exposure; }));
  EXPECT_TRUE(app.illumination().camera_hold_rect().empty());
  EXPECT_EQ(app.notifications().size(), 2u) << "the release is announced";
}

// The worker on a simulated still rig and the window over it, the simulator's camera controls
// handed to the window as the GUI's source factory hands them on: the operator's side of a sweep.
class RigWindow {
public:
  RigWindow(const SimulatorOptions& sim, int settle_frames) : worker_(options(settle_frames)) {
    worker_.post(command::SetSource{[this, sim] {
      auto source = make_simulated_source(sim);
      const std::lock_guard lock(mutex_);
      controls_ = source->camera_controls();
      return source;
    }});
    worker_.post(command::Start{});
    SessionActions actions;
    actions.camera_controls = [this] {
      const std::lock_guard lock(mutex_);
      return controls_;
    };
    app_.set_session_actions(actions);
  }

  Worker& worker() { return worker_; }
  Application& app() { return app_; }
  CameraState camera_state() {
    const std::lock_guard lock(mutex_);
    return controls_ ? controls_->state() : CameraState{};
  }
  // One frame of the window's loop: the latest snapshot drawn (skipped for "no window").
  void draw(OffscreenUi& ui) {
    if (with_window) ui.frame([&] { app_.draw(*worker_.snapshot()); });
  }
  // The window runs until the camera's state satisfies `done` (the simulator applies a change
  // with its next frame, so a moment after the window asked for it); false after 10 s.
  template <typename Done>
  bool run_until(OffscreenUi& ui, Done done) {
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    while (!done(camera_state())) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      draw(ui);
      std::this_thread::sleep_for(1ms);
    }
    return true;
  }
  // The operator confirms each power the wizard asks for, the window running between the steps;
  // returns the snapshot with the sweep's fitted response (or its failure).
  std::shared_ptr<const Snapshot> sweep(OffscreenUi& ui, const std::vector<double>& powers) {
    for (const double power : powers) {
      const auto asked = worker_.wait_for(
          [&](const Snapshot& s) { return s.illumination && s.illumination->requested_power_w() == power; }, 20s);
      EXPECT_EQ(asked->illumination->requested_power_w(), power) << asked->message;
      draw(ui);
      if (with_window) {
        EXPECT_TRUE(run_until(ui, [](const CameraState& c) { return c.locked; }))
            << "locked once the wizard asks for a power";
      }
      worker_.post(command::Sweep{sweep_command::Capture{power}});
    }
    const auto fitted = worker_.wait_for(
        [](const Snapshot& s) { return s.sweep_response && s.sweep_response->state != SweepResponse::State::Fitting; },
        60s);
    for (int i = 0; i < 3; ++i) draw(ui);
    return fitted;
  }

  bool with_window = true;

private:
  static WorkerOptions options(int settle_frames) {
    WorkerOptions o{.pacing = Pacing::AsFastAsPossible, .loop = true};
    o.pipeline.mode = PipelineMode::Quality;
    o.illumination = shipped_config();
    o.illumination.sweep.settle_frames = settle_frames;
    return o;
  }

  std::mutex mutex_;
  std::shared_ptr<CameraControls> controls_;
  Worker worker_;
  Application app_{gl::find_shader_dir(), [this](Command c) { worker_.post(std::move(c)); }};
};

double mean_response_error(const SweepResponse& response, const ResponseModel& truth) {
  const std::vector<double> G = response.response.inverse_table(256), G_true = truth.inverse_table(256);
  double sum = 0.0;
  for (std::size_t i = 0; i < 256; ++i) sum += std::abs(G[i] - G_true[i]) / 256.0;
  return sum;
}

// The simulated rig under its own auto exposure: the window locks the simulator's camera while the
// wizard sweeps and gives its auto exposure back after; the response comes out right (measured
// 0.03-0.08 grey levels). Without the window the auto exposure follows the lamp, and as the simulator
// reports each frame's exposure exactly the fit still holds (0.06-0.19): the lock is for cameras whose
// reported exposure is not the frame's, and for keeping the images' grey range wide.
TEST_F(IlluminationPanelTest, TheWindowLocksTheSimulatorsCameraForTheSweepAndGivesItBack) {
  SimulatorOptions sim = nirslam::testing::still_rig();
  sim.exposure_mode = ExposureMode::Auto;
  const std::vector<double> powers = {0, 5, 10, 20, 40, 65, 100, 150};
  for (const bool with_window : {true, false}) {
    ui_.reset();
    ui_ = std::make_unique<OffscreenUi>(1280, 800);
    RigWindow rig(sim, 20);  // 20 frames at each power for the auto exposure to settle
    rig.with_window = with_window;
    rig.worker().post(command::Sweep{sweep_command::Start{powers, 2}});
    const auto fitted = rig.sweep(*ui_, powers);
    if (with_window) {
      EXPECT_TRUE(rig.run_until(*ui_, [](const CameraState& c) { return !c.locked && c.auto_exposure; }))
          << "given back after the sweep";
    }
    rig.worker().post(command::Pause{});
    ASSERT_TRUE(fitted->sweep_response);
    const SweepResponse& response = *fitted->sweep_response;
    ASSERT_EQ(response.state, SweepResponse::State::Done) << response.reason;
    const double error = mean_response_error(response, sim.response);
    std::printf("sweep under auto exposure, %s: %.2f grey levels mean error, top grey %.0f\n",
                with_window ? "the window's lock" : "no lock", error, response.highest_grey);
    EXPECT_LT(error, with_window ? 0.5 : 2.0);
  }
}

// The street's sweep at 4 ms stops short of the top; the response row offers the advised exposure,
// and the sweep taken again there (the window sets the camera, the worker's wizard sweeps) meets
// the response target: the loop an operator goes through, end to end on the simulator's camera.
TEST_F(IlluminationPanelTest, ASweepThatStopsShortOffersTheAdvisedExposureAndTheSecondSweepMeetsTheTarget) {
  SimulatorOptions sim = nirslam::testing::still_rig();
  sim.scene = sim::SceneKind::Outdoor;
  const std::vector<double> powers = {0, 5, 10, 20, 40, 65, 100, 150};
  ui_.reset();
  ui_ = std::make_unique<OffscreenUi>(1280, 800);
  RigWindow rig(sim, 1);
  std::vector<double> held_ms;  // the exposure each sweep's frames were taken at
  const auto exposure_of = [](const Snapshot& s) { return s.frame && s.frame->exposure_ms ? *s.frame->exposure_ms : 0.0; };

  rig.worker().post(command::Sweep{sweep_command::Start{powers, 2}});
  const auto first = rig.sweep(*ui_, powers);
  ASSERT_TRUE(first->sweep_response && first->sweep_response->state == SweepResponse::State::Done)
      << (first->sweep_response ? first->sweep_response->reason : first->message);
  held_ms.push_back(exposure_of(*first));
  const SweepResponse& short_sweep = *first->sweep_response;
  EXPECT_NE(short_sweep.warning.find("about"), std::string::npos) << short_sweep.warning;
  EXPECT_GT(short_sweep.exposure_factor, 2.0);
  const double short_error = mean_response_error(short_sweep, sim.response);
  const ScreenRect again = rig.app().illumination().sweep_again_button_rect();
  ASSERT_FALSE(again.empty()) << "the response row offers the advised exposure";
  testing::save_if_requested(ui_->read_rgba(), "SweepAgainAtTheAdvisedExposure");

  testing::click_at(again.centre(), [&] { rig.draw(*ui_); });
  const auto second = rig.sweep(*ui_, powers);
  EXPECT_TRUE(rig.run_until(*ui_, [](const CameraState& c) { return !c.locked; })) << "given back after the second sweep";
  rig.worker().post(command::Pause{});
  ASSERT_TRUE(second->sweep_response && second->sweep_response->state == SweepResponse::State::Done)
      << (second->sweep_response ? second->sweep_response->reason : second->message);
  held_ms.push_back(exposure_of(*second));
  const SweepResponse& full_sweep = *second->sweep_response;
  const double full_error = mean_response_error(full_sweep, sim.response);
  std::printf("the street's sweep at 4 ms: top grey %.0f, %.2f grey levels mean error, advice %.1fx; again at the "
              "advice: top grey %.0f, %.2f grey levels\n",
              short_sweep.highest_grey, short_error, short_sweep.exposure_factor, full_sweep.highest_grey, full_error);
  // At the advised exposure, or at the simulated camera's longest (30 ms; it has no gain to add).
  const double reachable = std::min(short_sweep.exposure_factor, rig.camera_state().exposure_ms.maximum / held_ms[0]);
  EXPECT_NEAR(held_ms[1] / held_ms[0], reachable, 0.01 * reachable) << "the second sweep at the advised exposure";
  EXPECT_GT(full_sweep.highest_grey, kSweepAdvisedHighestGrey);
  EXPECT_TRUE(full_sweep.warning.empty()) << full_sweep.warning;
  EXPECT_GT(short_error, 1.0);  // measured 2.9-5.0 over runs (which frames the wizard takes varies)
  EXPECT_GT(short_error, 2.0 * full_error);
  EXPECT_LT(full_error, 1.0);  // measured 0.02-0.23
}

}  // namespace
}  // namespace nirslam::ui
