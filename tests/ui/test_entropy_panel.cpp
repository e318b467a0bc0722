// The entropy panel rendered headless from a hand-made snapshot: the gauge fill is proportional to
// the entropy, the history line sits at the right heights, clipping shows in its own plot.

#include <gtest/gtest.h>

#include "ui/panels/entropy_panel.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using testing::full_window;
using testing::near;
using testing::pixel;
using testing::Rgb;

// 200 frames: entropy 2 bits for frames 0..99, then 6 bits; saturation 3 % from frame 150.
Snapshot history_snapshot(double current_bits) {
  Frame frame;
  frame.image = cv::Mat(48, 64, CV_8UC1, cv::Scalar(100));
  frame.index = 199;
  Snapshot snapshot = testing::snapshot_with_frame(frame);
  snapshot.source.frame_count = 1000;  // longer than the plot span
  snapshot.quality_history.clear();
  for (int i = 0; i < 200; ++i) {
    QualitySample sample;
    sample.frame_index = i;
    sample.timestamp_s = i / 30.0;
    sample.quality.entropy_bits = i < 100 ? 2.0 : 6.0;
    sample.quality.saturated_fraction = i < 150 ? 0.0 : 0.03;
    sample.quality.black_fraction = 0.01;
    snapshot.quality_history.push_back(sample);
  }
  snapshot.quality.entropy_bits = current_bits;
  snapshot.quality.saturated_fraction = 0.03;
  snapshot.quality.black_fraction = 0.01;
  return snapshot;
}

class EntropyPanelTest : public testing::HeadlessGlTest {
protected:
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ui_ = std::make_unique<OffscreenUi>(520, 800);
  }
  void TearDown() override {
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  cv::Mat render(EntropyPanel& panel, const Snapshot& snapshot) {
    for (int i = 0; i < 2; ++i) ui_->frame([&] { full_window([&] { panel.draw(snapshot); }); });
    cv::Mat shot = ui_->read_rgba();
    testing::save_if_requested(shot, ::testing::UnitTest::GetInstance()->current_test_info()->name());
    return shot;
  }
  std::unique_ptr<OffscreenUi> ui_;
};

// The fraction of the gauge's middle row painted in the entropy colour.
double gauge_fill_fraction(const cv::Mat& shot, const ScreenRect& gauge) {
  const int y = static_cast<int>(gauge.centre().y);
  int filled = 0;
  for (int x = static_cast<int>(gauge.min.x); x < static_cast<int>(gauge.max.x); ++x)
    filled += near(pixel(shot, x, y), colours::entropy, 3) ? 1 : 0;
  return filled / static_cast<double>(gauge.width());
}

TEST_F(EntropyPanelTest, GaugeFillIsProportionalToTheEntropy) {
  EntropyPanel panel;
  for (const double bits : {6.0, 2.0, 7.5}) {
    SCOPED_TRACE(bits);
    const cv::Mat shot = render(panel, history_snapshot(bits));
    ASSERT_EQ(shot.cols, 520);
    ASSERT_EQ(shot.rows, 800);
    const ScreenRect& gauge = panel.gauge_rect();
    ASSERT_GT(gauge.width(), 400.0f) << "the gauge spans the panel";
    EXPECT_NEAR(gauge_fill_fraction(shot, gauge), bits / 8.0, 0.01);
    EXPECT_NEAR(panel.gauge_fill_rect().width() / gauge.width(), bits / 8.0, 0.005);
    // Past the fill the track is the frame background, not the fill colour.
    const Rgb track = pixel(shot, ImVec2(gauge.max.x - 3.0f, gauge.centre().y));
    EXPECT_FALSE(near(track, colours::entropy, 30)) << track;
  }
}

TEST_F(EntropyPanelTest, HistoryLineSitsAtTheEntropyOfEachFrame) {
  EntropyPanel panel;
  panel.history_frames = 200;
  const cv::Mat shot = render(panel, history_snapshot(6.0));
  const ScreenRect& plot = panel.entropy_plot_rect();
  ASSERT_GT(plot.width(), 300.0f);
  ASSERT_GT(plot.height(), 120.0f);

  // The line colour is in the plot area, along its whole width (200 frames over 200 frame slots).
  EXPECT_GT(testing::count_colour(shot, plot, colours::entropy, 3), static_cast<int>(plot.width()));

  // At frame 50 the line is at 2 bits, at frame 170 at 6 bits (x from 0 to 199 over the width).
  const auto line_y_at = [&](double frame) {
    const int x = static_cast<int>(plot.min.x + frame / 199.0 * plot.width());
    for (int y = static_cast<int>(plot.min.y); y < static_cast<int>(plot.max.y); ++y)
      if (near(pixel(shot, x, y), colours::entropy, 3)) return static_cast<float>(y);
    return -1.0f;
  };
  const auto expected_y = [&](double bits) { return plot.max.y - static_cast<float>(bits / 8.0) * plot.height(); };
  EXPECT_NEAR(line_y_at(50), expected_y(2.0), 3.0f);
  EXPECT_NEAR(line_y_at(170), expected_y(6.0), 3.0f);

  // Saturation (3 % from frame 150) in red and black (1 %) in blue, in the clipping plot.
  const ScreenRect& clip = panel.clipping_plot_rect();
  ASSERT_FALSE(clip.empty());
  EXPECT_GT(testing::count_colour(shot, clip, colours::saturated, 10), 20);
  EXPECT_GT(testing::count_colour(shot, clip, colours::black, 10), static_cast<int>(0.5f * clip.width()));
  // ... and none of the saturation line left of frame 150.
  ScreenRect early = clip;
  early.max.x = clip.min.x + 0.7f * clip.width();
  early.max.y = clip.max.y - 0.5f * clip.height();
  EXPECT_EQ(testing::count_colour(shot, early, colours::saturated, 10), 0);
}

TEST_F(EntropyPanelTest, HistogramShowsTheBinsOfTheCurrentFrame) {
  // Half the pixels at 50, half at 200: two bars, one bit of entropy.
  Frame frame;
  frame.image = cv::Mat(48, 64, CV_8UC1, cv::Scalar(50));
  frame.image.colRange(32, 64).setTo(200);
  EntropyPanel panel;
  const Snapshot snapshot = testing::snapshot_with_frame(frame);
  ASSERT_NEAR(snapshot.quality.entropy_bits, 1.0, 1e-9);
  const cv::Mat shot = render(panel, snapshot);
  const ScreenRect& h = panel.histogram_rect();
  ASSERT_GT(h.width(), 256.0f);
  const auto bar_pixels = [&](int bin) {
    ScreenRect column = h;
    column.min.x = h.min.x + (bin + 0.5f) * h.width() / 256.0f;
    column.max.x = column.min.x + 1.0f;
    return testing::count_colour(shot, column, colours::histogram, 3);
  };
  EXPECT_GT(bar_pixels(50), static_cast<int>(0.8f * h.height())) << "full-height bar at bin 50";
  EXPECT_GT(bar_pixels(200), static_cast<int>(0.8f * h.height())) << "full-height bar at bin 200";
  EXPECT_EQ(bar_pixels(120), 0) << "nothing between";
  EXPECT_EQ(bar_pixels(10), 0);
}

TEST_F(EntropyPanelTest, EmptySnapshotDrawsAnEmptyGaugeAndPlots) {
  EntropyPanel panel;
  const cv::Mat shot = render(panel, Snapshot{});
  EXPECT_EQ(panel.gauge_fill_rect().width(), 0.0f);
  EXPECT_EQ(testing::count_colour(shot, panel.gauge_rect(), colours::entropy, 3), 0);
  EXPECT_FALSE(panel.entropy_plot_rect().empty());
}

}  // namespace
}  // namespace nirslam::ui
