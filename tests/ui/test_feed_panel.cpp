// The feed panel rendered headless from hand-made frames: the grey ramp appears where the image is
// drawn, normalised by the bit depth; clipped pixels are marked red / blue only when asked; the
// aspect ratio is kept; the mouse wheel zooms about the cursor and dragging pans.

#include <cstdint>

#include <gtest/gtest.h>

#include "ui/gl/shader.hpp"
#include "ui/colour_maps.hpp"
#include "ui/panels/feed_panel.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using testing::full_window;
using testing::image_to_screen;
using testing::near;
using testing::pixel;
using testing::Rgb;

constexpr int kWidth = 256;
constexpr int kHeight = 128;
constexpr int kBlock = 32;  // saturated block top-right, black block bottom-left

// A horizontal ramp over most of the range (never at the clipping codes), with a saturated block
// in the top-right corner and a black block in the bottom-left corner.
Frame ramp_frame(int bit_depth) {
  const bool sixteen = bit_depth > 8;
  const double top = static_cast<double>((1u << bit_depth) - 1u);
  Frame frame;
  frame.bit_depth = bit_depth;
  frame.image = cv::Mat(kHeight, kWidth, sixteen ? CV_16UC1 : CV_8UC1);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      double value = top * (0.0625 + 0.875 * x / (kWidth - 1.0));
      if (x >= kWidth - kBlock && y < kBlock) value = top;
      if (x < kBlock && y >= kHeight - kBlock) value = 0.0;
      if (sixteen)
        frame.image.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(std::lround(value));
      else
        frame.image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(std::lround(value));
    }
  frame.index = 4;
  frame.timestamp_s = 0.4;
  frame.exposure_ms = 8.0;
  frame.name = "ramp";
  return frame;
}

// The grey the shader should show for image column x (away from the blocks).
int expected_grey(int x) { return static_cast<int>(std::lround(255.0 * (0.0625 + 0.875 * x / (kWidth - 1.0)))); }

class FeedPanelTest : public testing::HeadlessGlTest {
protected:
  void render(FeedPanel& panel, const Snapshot& snapshot, int frames = 2) {
    for (int i = 0; i < frames; ++i) ui_->frame([&] { full_window([&] { panel.draw(snapshot); }); });
    testing::save_if_requested(ui_->read_rgba(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ui_ = std::make_unique<OffscreenUi>(800, 600);
  }
  void TearDown() override {
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  std::unique_ptr<OffscreenUi> ui_;
};

void expect_ramp_and_clipping(const cv::Mat& shot, const FeedPanel& panel, bool highlighted) {
  const ScreenRect& image = panel.image_rect();
  const float s = panel.scale();
  // Sample the ramp along the middle row (between the two blocks).
  int previous = -1;
  for (int x : {40, 70, 100, 128, 160, 190, 215}) {
    const Rgb p = pixel(shot, image_to_screen(image, s, x, kHeight / 2));
    const int g = expected_grey(x);
    EXPECT_TRUE(near(p, Rgb{g, g, g}, 3)) << "column " << x << ": " << p << ", expected grey " << g;
    EXPECT_GT(p.r, previous) << "the ramp must brighten to the right";
    previous = p.r;
  }
  const Rgb saturated = pixel(shot, image_to_screen(image, s, kWidth - kBlock / 2, kBlock / 2));
  const Rgb black = pixel(shot, image_to_screen(image, s, kBlock / 2, kHeight - kBlock / 2));
  if (highlighted) {
    EXPECT_TRUE(near(saturated, colours::saturated, 2)) << "saturated block: " << saturated;
    EXPECT_TRUE(near(black, colours::black, 2)) << "black block: " << black;
  } else {
    EXPECT_TRUE(near(saturated, Rgb{255, 255, 255}, 1)) << "saturated block unmarked: " << saturated;
    EXPECT_TRUE(near(black, Rgb{0, 0, 0}, 1)) << "black block unmarked: " << black;
  }
}

TEST_F(FeedPanelTest, ShowsTheEightBitRampFittedWithClippingHighlighted) {
  FeedPanel panel(gl::find_shader_dir());
  ASSERT_TRUE(panel.highlight_clipping) << "highlighting is on by default";
  const Snapshot snapshot = testing::snapshot_with_frame(ramp_frame(8));
  render(panel, snapshot);
  const cv::Mat shot = ui_->read_rgba();
  ASSERT_EQ(shot.cols, 800);
  ASSERT_EQ(shot.rows, 600);

  // Fitted: the 2:1 frame spans the view's width, centred, aspect ratio kept.
  const ScreenRect& view = panel.view_rect();
  const ScreenRect& image = panel.image_rect();
  ASSERT_FALSE(view.empty());
  EXPECT_NEAR(image.width(), view.width(), 1.0f);
  EXPECT_NEAR(image.width() / image.height(), 2.0f, 0.02f);
  EXPECT_NEAR(image.centre().y, view.centre().y, 1.0f);
  EXPECT_NEAR(panel.scale(), view.width() / kWidth, 0.01f);

  expect_ramp_and_clipping(shot, panel, true);

  // Around the image (letterbox above it, clear of the corner overlays): the feed background.
  const Rgb letterbox = pixel(shot, ImVec2(view.centre().x, 0.5f * (view.min.y + image.min.y)));
  EXPECT_TRUE(near(letterbox, colours::feed_bg, 2)) << letterbox;
  // The frame info overlay is drawn over the image: real content, not a blank panel.
  EXPECT_GT(testing::grey_stddev(shot, view), 20.0);
}

TEST_F(FeedPanelTest, ClippedPixelsStayGreyWhenHighlightingIsOff) {
  FeedPanel panel(gl::find_shader_dir());
  panel.highlight_clipping = false;
  render(panel, testing::snapshot_with_frame(ramp_frame(8)));
  expect_ramp_and_clipping(ui_->read_rgba(), panel, false);
}

TEST_F(FeedPanelTest, TenBitFramesInSixteenBitWordsAreNormalisedByTheirBitDepth) {
  // Codes 0..1023 in a CV_16UC1 image: full white at 1023, not at 65535, and 1023 is saturated.
  FeedPanel panel(gl::find_shader_dir());
  render(panel, testing::snapshot_with_frame(ramp_frame(10)));
  expect_ramp_and_clipping(ui_->read_rgba(), panel, true);
}

TEST_F(FeedPanelTest, MouseWheelZoomsAboutTheCursorAndDragPans) {
  FeedPanel panel(gl::find_shader_dir());
  const Snapshot snapshot = testing::snapshot_with_frame(ramp_frame(8));
  render(panel, snapshot);
  const ScreenRect before = panel.image_rect();
  const float scale_before = panel.scale();

  // One wheel notch with the cursor on image pixel (64, 64).
  const ImVec2 cursor = image_to_screen(before, scale_before, 64, 64);
  ImGuiIO& io = ImGui::GetIO();
  io.MousePos = cursor;
  render(panel, snapshot, 1);  // hover first, as a real mouse would
  io.MouseWheel = 1.0f;
  render(panel, snapshot, 1);
  io.MouseWheel = 0.0f;
  render(panel, snapshot, 1);
  EXPECT_NEAR(panel.zoom(), 1.25f, 1e-4f);
  EXPECT_NEAR(panel.scale(), scale_before * 1.25f, 1e-3f);
  EXPECT_NEAR(panel.image_rect().width(), before.width() * 1.25f, 1.5f);
  // The image point under the cursor stayed under it (within rounding).
  const ImVec2 after = image_to_screen(panel.image_rect(), panel.scale(), 64, 64);
  EXPECT_NEAR(after.x, cursor.x, 1.5f);
  EXPECT_NEAR(after.y, cursor.y, 1.5f);

  // Drag 40 px left and 20 px up: the image follows.
  const ScreenRect zoomed = panel.image_rect();
  io.MouseDown[0] = true;
  render(panel, snapshot, 1);
  io.MousePos = ImVec2(cursor.x - 40.0f, cursor.y - 20.0f);
  render(panel, snapshot, 1);
  io.MouseDown[0] = false;
  render(panel, snapshot, 1);
  EXPECT_NEAR(panel.image_rect().min.x, zoomed.min.x - 40.0f, 1.0f);
  EXPECT_NEAR(panel.image_rect().min.y, zoomed.min.y - 20.0f, 1.0f);

  // Fit restores the whole frame.
  panel.fit();
  io.MousePos = ImVec2(-1.0f, -1.0f);
  render(panel, snapshot, 1);
  EXPECT_NEAR(panel.image_rect().width(), before.width(), 0.5f);
  EXPECT_NEAR(panel.image_rect().min.x, before.min.x, 0.5f);
}

TEST_F(FeedPanelTest, WithoutAFrameItSaysHowToGetOne) {
  FeedPanel panel(gl::find_shader_dir());
  Snapshot empty;
  render(panel, empty);
  const cv::Mat shot = ui_->read_rgba();
  EXPECT_TRUE(panel.image_rect().empty());
  // The message is drawn: the view is not uniformly the background.
  EXPECT_GT(testing::count_colour(shot, panel.view_rect(), colours::feed_bg, 1),
            static_cast<int>(0.9f * panel.view_rect().width() * panel.view_rect().height()));
  EXPECT_GT(testing::grey_stddev(shot, panel.view_rect()), 1.0);
}


TEST_F(FeedPanelTest, CorrectedViewShowsTheFrameTheOdometrySees) {
  FeedPanel panel(gl::find_shader_dir());
  Snapshot snapshot = testing::snapshot_with_frame(ramp_frame(8));
  // G(I)/V of a made-up model: a flat 200 everywhere, so the corrected view is uniform.
  snapshot.corrected_image = cv::Mat(kHeight, kWidth, CV_32FC1, cv::Scalar(200.0f));
  panel.highlight_clipping = false;
  panel.show_corrected = true;
  render(panel, snapshot);
  ASSERT_TRUE(panel.showing_corrected());
  const cv::Mat shot = ui_->read_rgba();
  const ScreenRect& image = panel.image_rect();
  for (int x : {40, 128, 215})
    EXPECT_TRUE(near(pixel(shot, image_to_screen(image, panel.scale(), x, kHeight / 2)), Rgb{200, 200, 200}, 3)) << x;
  // Without a corrected image (a mode without calibration) the raw frame stays.
  snapshot.corrected_image = cv::Mat();
  render(panel, snapshot);
  EXPECT_FALSE(panel.showing_corrected());
  const cv::Mat raw = ui_->read_rgba();
  EXPECT_TRUE(near(pixel(raw, image_to_screen(panel.image_rect(), panel.scale(), 40, kHeight / 2)),
                   Rgb{expected_grey(40), expected_grey(40), expected_grey(40)}, 3));
}


TEST_F(FeedPanelTest, TrackedPointsAreDrawnWhereTheyProjectColouredByDepth) {
  FeedPanel panel(gl::find_shader_dir());
  Snapshot snapshot = testing::snapshot_with_frame(ramp_frame(8));
  auto view = std::make_shared<TrajectoryView>();
  view->enabled = true;
  view->current_pixels = {Eigen::Vector2f(60.0f, 30.0f), Eigen::Vector2f(190.0f, 90.0f)};
  view->current_depths = {1.0f, 4.0f};  // near, far
  snapshot.trajectory = view;
  panel.highlight_clipping = false;
  render(panel, snapshot);
  EXPECT_EQ(panel.points_drawn(), 2);
  const cv::Mat shot = ui_->read_rgba();
  const ScreenRect& image = panel.image_rect();
  EXPECT_TRUE(near(pixel(shot, image_to_screen(image, panel.scale(), 60, 30)), time_colour(1.0f), 12)) << "near: red end";
  EXPECT_TRUE(near(pixel(shot, image_to_screen(image, panel.scale(), 190, 90)), time_colour(0.0f), 12)) << "far: blue end";
  panel.show_points = false;
  render(panel, snapshot);
  EXPECT_EQ(panel.points_drawn(), 0);
}

}  // namespace
}  // namespace nirslam::ui
