// The whole operator UI on a running worker with the demo source, rendered headless: the tiled
// layout fills the display without overlaps, every panel shows real content, the controls post
// commands to the worker, and `run_headless` (what `nirslam gui --headless` runs) writes the PNG.

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "frontends/headless_frontend.hpp"
#include "nirslam/config/illumination_config.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/sources/demo_source.hpp"
#include "nirslam/worker/worker.hpp"
#include "ui/application.hpp"
#include "ui/gl/shader.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using namespace std::chrono_literals;
using testing::near;
using testing::pixel;

bool overlaps(const ScreenRect& a, const ScreenRect& b) {
  return a.min.x < b.max.x && b.min.x < a.max.x && a.min.y < b.max.y && b.min.y < a.max.y;
}

class LayoutTest : public testing::HeadlessGlTest {};

TEST_F(LayoutTest, TilesFillTheDisplayWithoutOverlapAtAnySize) {
  OffscreenUi offscreen(1280, 800);
  Application app(gl::find_shader_dir(), {});
  for (const ImVec2 display : {ImVec2(1280, 800), ImVec2(800, 500), ImVec2(2560, 1440)}) {
    SCOPED_TRACE(display.x);
    Application::Layout layout;
    offscreen.frame([&] { layout = app.compute_layout(display); });
    const ScreenRect tiles[] = {layout.controls, layout.feed, layout.view3d, layout.entropy, layout.strip, layout.status};
    constexpr int kTiles = 6;
    float area = 0.0f;
    for (int i = 0; i < kTiles; ++i) {
      EXPECT_FALSE(tiles[i].empty()) << "tile " << i;
      area += tiles[i].width() * tiles[i].height();
      for (int j = i + 1; j < kTiles; ++j) EXPECT_FALSE(overlaps(tiles[i], tiles[j])) << i << " overlaps " << j;
    }
    EXPECT_FLOAT_EQ(area, display.x * display.y) << "the tiles cover the display";
    EXPECT_EQ(layout.controls.min.y, 0.0f);
    EXPECT_EQ(layout.status.max.y, display.y);
    // Feed and 3-D view side by side, the feed wider; the quality column on the right.
    EXPECT_EQ(layout.feed.max.x, layout.view3d.min.x);
    EXPECT_EQ(layout.view3d.max.x, layout.entropy.min.x);
    EXPECT_EQ(layout.feed.min.y, layout.view3d.min.y);
    EXPECT_EQ(layout.feed.max.y, layout.view3d.max.y);
    EXPECT_GT(layout.feed.width(), layout.view3d.width()) << "the feed gets the larger share";
    EXPECT_GE(layout.entropy.width(), 380.0f);
    // The illumination / photometric strip sits under both views, as wide as they are, shorter.
    EXPECT_EQ(layout.strip.min.y, layout.feed.max.y);
    EXPECT_EQ(layout.strip.min.x, layout.feed.min.x);
    EXPECT_EQ(layout.strip.max.x, layout.view3d.max.x);
    EXPECT_EQ(layout.strip.max.y, layout.status.min.y);
    EXPECT_GE(layout.strip.height(), std::min(240.0f, std::round(0.45f * (layout.status.min.y - layout.controls.max.y))));
    EXPECT_GT(layout.feed.height(), layout.strip.height());
  }
}

TEST_F(LayoutTest, RendersTheRunningDemoInEveryPanel) {
  WorkerOptions options{.pacing = Pacing::AsFastAsPossible};
  options.illumination = load_illumination_config(std::filesystem::path(NIRSLAM_SOURCE_DIR) / "config/illumination.yaml");
  Worker worker(options);
  worker.post(command::SetSource{[] { return make_demo_source(); }});
  OffscreenUi offscreen(1280, 800);
  Application app(gl::find_shader_dir(), [&worker](Command c) { worker.post(std::move(c)); });

  // Start through the UI, as the operator would: the Space shortcut has no key map headless, so
  // post the command the Start button posts, then render while the worker runs.
  worker.post(command::Start{});
  std::shared_ptr<const Snapshot> shown = worker.snapshot();
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (shown->frames_processed < 30 && std::chrono::steady_clock::now() < deadline) {
    shown = worker.wait_for([](const Snapshot& s) { return s.frames_processed >= 30; }, 30ms);
    offscreen.frame([&] { app.draw(*shown); });
  }
  ASSERT_GE(shown->frames_processed, 30) << shown->message;
  worker.post(command::Pause{});
  for (int i = 0; i < 2; ++i) offscreen.frame([&] { app.draw(*shown); });
  const cv::Mat shot = offscreen.read_rgba();
  testing::save_if_requested(shot, "RendersTheRunningDemoInEveryPanel");
  ASSERT_EQ(shot.cols, 1280);
  ASSERT_EQ(shot.rows, 800);

  // The feed shows the demo's textured wall: a 4:3 image with real structure.
  const ScreenRect& image = app.feed().image_rect();
  ASSERT_FALSE(image.empty());
  EXPECT_NEAR(image.width() / image.height(), 640.0f / 480.0f, 0.01f);
  EXPECT_TRUE(overlaps(image, app.layout().feed));
  ScreenRect middle = image;  // clear of the overlays in the corners
  middle.min = ImVec2(image.min.x + 0.3f * image.width(), image.min.y + 0.4f * image.height());
  middle.max = ImVec2(image.max.x - 0.3f * image.width(), image.max.y - 0.1f * image.height());
  EXPECT_GT(testing::grey_stddev(shot, middle), 8.0);

  // The entropy gauge shows the shown snapshot's value; the history has its line.
  const ScreenRect& gauge = app.entropy().gauge_rect();
  EXPECT_GT(shown->quality.entropy_bits, 3.0);
  EXPECT_NEAR(app.entropy().gauge_fill_rect().width() / gauge.width(), shown->quality.entropy_bits / 8.0, 0.005);
  EXPECT_GT(testing::count_colour(shot, app.entropy().entropy_plot_rect(), colours::entropy, 3), 10);

  // The illumination strip shows the live verdict on the demo's well-lit frames (green) and the
  // prior's recommended power for the default scene on its plot.
  const ScreenRect& banner = app.illumination().banner_rect();
  ASSERT_FALSE(banner.empty());
  EXPECT_TRUE(overlaps(banner, app.layout().strip));
  EXPECT_EQ(shown->exposure.verdict, ExposureVerdict::Ok) << shown->exposure.message;
  EXPECT_TRUE(near(pixel(shot, ImVec2(banner.max.x - 4.0f, banner.centre().y)), colours::banner_ok, 3));
  EXPECT_FALSE(app.illumination().plot_rect().empty());
  EXPECT_TRUE(app.illumination().recommended_marker().has_value());

  // The control strip's state badge is in the "running" colour, and the status line has text.
  EXPECT_EQ(shown->state, WorkerState::Running);
  EXPECT_GT(testing::count_colour(shot, app.layout().controls, colours::state_running, 3), 10);
  EXPECT_GT(testing::grey_stddev(shot, app.layout().status), 3.0);

  // The worker paused on the command; the UI never waited for it.
  const auto paused = worker.wait_for([](const Snapshot& s) { return s.state == WorkerState::Paused; }, 5s);
  EXPECT_EQ(paused->state, WorkerState::Paused);
}

TEST_F(LayoutTest, StepShortcutPostsAStepCommand) {
  Worker worker;
  worker.post(command::SetSource{[] { return make_demo_source(); }});
  const auto ready = worker.wait_for([](const Snapshot& s) { return !s.source.kind.empty(); }, 5s);
  ASSERT_FALSE(ready->source.kind.empty());
  OffscreenUi offscreen(1024, 640);
  Application app(gl::find_shader_dir(), [&worker](Command c) { worker.post(std::move(c)); });
  ImGui::GetIO().AddInputCharacter('s');
  offscreen.frame([&] { app.draw(*worker.snapshot()); });
  const auto stepped = worker.wait_for([](const Snapshot& s) { return s.frames_processed == 1; }, 5s);
  EXPECT_EQ(stepped->frames_processed, 1);
  EXPECT_EQ(stepped->state, WorkerState::Paused);
}

TEST_F(LayoutTest, HeadlessFrontEndWritesTheScreenshot) {
  const auto dir = std::filesystem::temp_directory_path() / ("nirslam_ui_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto png = dir / "gui.png";
  {
    Worker worker;
    worker.post(command::SetSource{[] { return make_demo_source(); }});
    app::HeadlessOptions options;
    options.width = 960;
    options.height = 600;
    options.frames = 20;
    options.screenshot = png;
    const app::HeadlessResult result = app::run_headless(worker, options);
    EXPECT_TRUE(result.reached_frames);
    EXPECT_GE(result.frames_processed, 20);
    EXPECT_GE(result.ui_frames, 3);
    EXPECT_EQ(result.screenshot, png);
    EXPECT_FALSE(result.renderer.empty());
  }
  const cv::Mat written = nirslam::read_image(png, nirslam::ImageReadMode::Bgr);
  ASSERT_FALSE(written.empty()) << png;
  EXPECT_EQ(written.cols, 960);
  EXPECT_EQ(written.rows, 600);
  cv::Scalar mean;
  cv::Scalar stddev;
  cv::meanStdDev(written, mean, stddev);
  EXPECT_GT(stddev[0], 10.0) << "not a blank image";

  // A screenshot into a missing folder is an error naming it.
  Worker worker;
  worker.post(command::SetSource{[] { return make_demo_source(); }});
  app::HeadlessOptions bad;
  bad.frames = 2;
  bad.screenshot = dir / "missing" / "gui.png";
  try {
    app::run_headless(worker, bad);
    ADD_FAILURE() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "missing").string()), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace nirslam::ui
