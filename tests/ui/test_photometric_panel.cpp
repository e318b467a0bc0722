// The photometric panel rendered headless from hand-made estimates: the response, inverse response
// and vignette curves sit where the models put them, the truth is overlaid, the vignette map is
// darker at the corners, and the exposure history is drawn.

#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "ui/panels/photometric_panel.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using testing::full_window;
using testing::near;
using testing::pixel;

std::shared_ptr<PhotometricView> estimate_view() {
  auto view = std::make_shared<PhotometricView>();
  view->enabled = true;
  view->response = ResponseModel::from_preset(ResponsePreset::Gamma);
  view->vignette = VignetteModel{Eigen::Vector3d(-0.35, 0.10, -0.05)};
  view->true_response = ResponseModel::from_preset(ResponsePreset::Linear);
  view->true_vignette = VignetteModel{Eigen::Vector3d(-0.2, 0.0, 0.0)};
  view->model_version = 3;
  view->converged = true;
  view->keyframes = 12;
  view->points = 800;
  view->iterations = 9;
  view->ambiguity = "known exposures (reported by the source)";
  view->lamp_term = "lamp term: 1234 odometry points";
  for (int i = 0; i < 200; ++i) {
    ExposurePoint p;
    p.frame_index = i;
    p.timestamp_s = i / 30.0;
    p.estimated = static_cast<float>(5.0 + 3.0 * std::sin(i / 20.0));
    p.reference = static_cast<float>(5.0 + 3.0 * std::sin(i / 20.0) + 0.2);
    p.keyframe = i % 15 == 0;
    view->exposures.push_back(p);
  }
  return view;
}

class PhotometricPanelTest : public testing::HeadlessGlTest {
protected:
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ui_ = std::make_unique<OffscreenUi>(1100, 360);
  }
  void TearDown() override {
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  cv::Mat render(PhotometricPanel& panel, const Snapshot& snapshot) {
    for (int i = 0; i < 2; ++i) ui_->frame([&] { full_window([&] { panel.draw(snapshot); }); });
    cv::Mat shot = ui_->read_rgba();
    testing::save_if_requested(shot, ::testing::UnitTest::GetInstance()->current_test_info()->name());
    return shot;
  }
  // Whether `colour` appears within `radius` pixels of the data point (x, y) of a plot area.
  static bool colour_at(const cv::Mat& shot, const ScreenRect& area, double u, double v, ImU32 colour, int radius = 3) {
    const int cx = static_cast<int>(area.min.x + u * area.width());
    const int cy = static_cast<int>(area.max.y - v * area.height());
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx)
        if (near(pixel(shot, cx + dx, cy + dy), colour, 30)) return true;
    return false;
  }
  std::unique_ptr<OffscreenUi> ui_;
};

TEST_F(PhotometricPanelTest, CurvesSitWhereTheModelsPutThem) {
  Snapshot snapshot;
  const auto view = estimate_view();
  snapshot.photometric = view;
  PhotometricPanel panel;
  const cv::Mat shot = render(panel, snapshot);
  const ScreenRect& response = panel.response_plot_rect();
  const ScreenRect& inverse = panel.inverse_plot_rect();
  const ScreenRect& vignette = panel.vignette_plot_rect();
  ASSERT_FALSE(response.empty());
  ASSERT_FALSE(inverse.empty());
  ASSERT_FALSE(vignette.empty());
  // Response: estimate (gamma) above the diagonal, truth (linear) on it, at X = 0.3.
  EXPECT_TRUE(colour_at(shot, response, 0.3, view->response(0.3), colours::estimate));
  EXPECT_TRUE(colour_at(shot, response, 0.3, 0.3, colours::ground_truth));
  EXPECT_FALSE(colour_at(shot, response, 0.3, 0.3, colours::estimate, 1));
  // Inverse response: G(y) below the diagonal for a gamma curve.
  EXPECT_TRUE(colour_at(shot, inverse, 0.5, view->response.inverse(0.5), colours::estimate));
  // Vignette at r = 0.8, on the plot's axis range (its lower end is the lowest V rounded down).
  const double lo = std::floor(std::min((*view->true_vignette)(1.0), view->vignette(1.0)) * 10.0 - 0.5) / 10.0;
  const double hi = 1.02;
  EXPECT_TRUE(colour_at(shot, vignette, 0.8, (view->vignette(0.8) - lo) / (hi - lo), colours::estimate));
  EXPECT_TRUE(colour_at(shot, vignette, 0.8, ((*view->true_vignette)(0.8) - lo) / (hi - lo), colours::ground_truth));
}

TEST_F(PhotometricPanelTest, UnderTheLampTheHaloFactorIsTheTruthDrawn) {
  Snapshot snapshot;
  auto view = estimate_view();
  // A steep halo (lens times a 30-degree beam): the truth line follows it, not the lens alone.
  view->true_halo = VignetteModel{Eigen::Vector3d(-1.2, 0.6, -0.15)};
  snapshot.photometric = view;
  PhotometricPanel panel;
  const cv::Mat shot = render(panel, snapshot);
  const ScreenRect& vignette = panel.vignette_plot_rect();
  ASSERT_FALSE(vignette.empty());
  const double lo = std::floor(std::min((*view->true_halo)(1.0), view->vignette(1.0)) * 10.0 - 0.5) / 10.0;
  const double hi = 1.02;
  const double halo = (*view->true_halo)(0.8), lens = (*view->true_vignette)(0.8);
  ASSERT_GT(lens - halo, 0.15);
  EXPECT_TRUE(colour_at(shot, vignette, 0.8, (halo - lo) / (hi - lo), colours::ground_truth));
  EXPECT_FALSE(colour_at(shot, vignette, 0.8, (lens - lo) / (hi - lo), colours::ground_truth, 1));
}

TEST_F(PhotometricPanelTest, ALampTheModeDoesNotModelIsFlagged) {
  Snapshot snapshot;
  auto view = estimate_view();
  view->lamp_term.clear();  // calibration alone has no lamp term
  snapshot.photometric = view;
  const auto amber_pixels = [&](const cv::Mat& shot, float top, float bottom) {
    int n = 0;
    for (int y = static_cast<int>(top); y < static_cast<int>(bottom); ++y)
      for (int x = 0; x < shot.cols; ++x) n += near(pixel(shot, x, y), colours::state_paused, 40);
    return n;
  };
  PhotometricPanel quiet;
  const cv::Mat without = render(quiet, snapshot);
  const float status_bottom = quiet.response_plot_rect().min.y - 20.0f;
  view->lamp_not_modelled = true;
  PhotometricPanel flagged;
  const cv::Mat with = render(flagged, snapshot);
  // The amber words beside the legend, in the status row (the badge is green: converged).
  EXPECT_GT(amber_pixels(with, 0.0f, status_bottom), amber_pixels(without, 0.0f, status_bottom) + 40);
}

// In a narrow panel the status items flow onto new lines instead of running off its edge: the
// amber lamp flag is drawn whole (as many amber pixels as in a wide panel), and the long texts
// are cut with an ellipsis inside the window.
TEST_F(PhotometricPanelTest, StatusItemsWrapInANarrowPanel) {
  Snapshot snapshot;
  auto view = estimate_view();
  view->lamp_not_modelled = true;
  view->lamp_term = "lamp term: 876 odometry points, 92 tracked patches";
  view->ambiguity = "gamma and scale from the known exposures (reported by the source), the irradiance scale by the "
                    "smoothest continuation of log G above the observed grey range";
  view->lamp_offset = "lamp offset: not determined along y: sigma 0.00824 > 0.00805 (the poses do not see the lamp's "
                      "falloff change enough) (92 of 934 window points)";
  snapshot.photometric = view;
  const auto amber_above = [&](const cv::Mat& shot, float bottom) {
    int n = 0;
    for (int y = 0; y < static_cast<int>(bottom); ++y)
      for (int x = 0; x < shot.cols; ++x) n += near(pixel(shot, x, y), colours::state_paused, 40);
    return n;
  };
  PhotometricPanel wide;
  const cv::Mat wide_shot = render(wide, snapshot);
  const int amber_wide = amber_above(wide_shot, wide.response_plot_rect().min.y - 20.0f);

  ui_.reset();  // one ImGui context at a time
  ui_ = std::make_unique<OffscreenUi>(560, 420);
  PhotometricPanel narrow;
  const cv::Mat shot = render(narrow, snapshot);
  const float plots_top = narrow.response_plot_rect().min.y;
  EXPECT_GT(amber_wide, 40);
  EXPECT_NEAR(amber_above(shot, plots_top - 20.0f), amber_wide, 0.1 * amber_wide) << "the flag drawn whole";
  // Nothing written into the window's right padding: every status text ends inside.
  const int padding = static_cast<int>(ImGui::GetStyle().WindowPadding.x);
  int in_padding = 0;
  for (int y = 0; y < static_cast<int>(plots_top) - 32; ++y)  // above the plots' captions
    for (int x = shot.cols - padding + 1; x < shot.cols; ++x) {
      const testing::Rgb c = pixel(shot, x, y);
      in_padding += c.r + c.g + c.b > 300 ? 1 : 0;
    }
  EXPECT_EQ(in_padding, 0);
}

TEST_F(PhotometricPanelTest, LampBeamAndOffsetTakeTheirOwnRow) {
  Snapshot snapshot;
  auto view = estimate_view();
  snapshot.photometric = view;
  PhotometricPanel without;
  render(without, snapshot);
  const float plots_top_without = without.response_plot_rect().min.y;
  view->lamp_beam = "lamp beam cos^4.82 (half angle 30.0 deg) = halo / lens vignette";
  view->lamp_offset = "lamp offset (0.000, 0.020, 0.000) +- (0.001, 0.002, 0.001) from 800 points, not applied";
  PhotometricPanel with;
  const cv::Mat shot = render(with, snapshot);
  const float plots_top = with.response_plot_rect().min.y;
  EXPECT_GT(plots_top, plots_top_without + 8.0f) << "a row for the lamp's beam and offset";
  // The row holds text: light pixels between the status line and the plots.
  int bright = 0;
  for (int y = static_cast<int>(plots_top_without); y < static_cast<int>(plots_top); ++y)
    for (int x = 10; x < 600; ++x) {
      const testing::Rgb c = pixel(shot, x, y);
      if (c.r + c.g + c.b > 300) ++bright;
    }
  EXPECT_GT(bright, 100);
}

TEST_F(PhotometricPanelTest, VignetteMapIsDarkerAtTheCorners) {
  Snapshot snapshot;
  snapshot.photometric = estimate_view();
  PhotometricPanel panel;
  const cv::Mat shot = render(panel, snapshot);
  const ScreenRect& map = panel.vignette_map_rect();
  ASSERT_FALSE(map.empty());
  const auto brightness = [&](float x, float y) {
    const testing::Rgb c = pixel(shot, static_cast<int>(x), static_cast<int>(y));
    return c.r + c.g + c.b;
  };
  const int centre = brightness(map.centre().x, map.centre().y);
  const int corner = brightness(map.max.x - 3.0f, map.min.y + 3.0f);
  EXPECT_GT(centre, corner + 150);
}

TEST_F(PhotometricPanelTest, ExposureHistoryAndKeyframesAreDrawn) {
  Snapshot snapshot;
  snapshot.photometric = estimate_view();
  PhotometricPanel panel;
  const cv::Mat shot = render(panel, snapshot);
  const ScreenRect& plot = panel.exposure_plot_rect();
  ASSERT_FALSE(plot.empty());
  EXPECT_GT(testing::count_colour(shot, plot, colours::estimate, 20), 200);
  EXPECT_GT(testing::count_colour(shot, plot, colours::ground_truth, 20), 100);
  EXPECT_GT(testing::count_colour(shot, plot, colours::keyframe_mark, 20), 10);
}

// Outside the grey range and beyond the radius the back end's samples reach, the curves are the
// model's continuation: the plots shade those parts, the map washes out its corners.
TEST_F(PhotometricPanelTest, UnmeasuredPartsOfTheCurvesAreShaded) {
  Snapshot snapshot;
  auto view = estimate_view();
  snapshot.photometric = view;
  PhotometricPanel plain;
  const cv::Mat before = render(plain, snapshot);
  view->grey_low = 40.0;
  view->grey_high = 150.0;
  view->radius_high = 0.7;
  PhotometricPanel panel;
  const cv::Mat shot = render(panel, snapshot);
  // Mean brightness (r + g + b) of a 5 x 5 box at data position (u, v) of a plot.
  const auto brightness = [](const cv::Mat& image, const ScreenRect& area, double u, double v) {
    const int cx = static_cast<int>(area.min.x + u * area.width());
    const int cy = static_cast<int>(area.max.y - v * area.height());
    int sum = 0;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx) {
        const testing::Rgb c = pixel(image, cx + dx, cy + dy);
        sum += c.r + c.g + c.b;
      }
    return sum / 25;
  };
  // Background away from the curves and grid lines: grey 13 (below the range) against grey 102
  // (inside) on the inverse response; r = 0.9 against r = 0.3 on the vignette.
  const ScreenRect& inverse = panel.inverse_plot_rect();
  const ScreenRect& vignette = panel.vignette_plot_rect();
  EXPECT_GT(brightness(shot, inverse, 0.05, 0.6), brightness(shot, inverse, 0.4, 0.6) + 12);
  EXPECT_EQ(brightness(shot, inverse, 0.4, 0.6), brightness(before, plain.inverse_plot_rect(), 0.4, 0.6));
  EXPECT_GT(brightness(shot, inverse, 0.9, 0.1), brightness(before, plain.inverse_plot_rect(), 0.9, 0.1) + 12);
  EXPECT_GT(brightness(shot, vignette, 0.9, 0.12), brightness(shot, vignette, 0.3, 0.12) + 12);
  // The response f over irradiance: shaded above G(150) (0.36 for this gamma estimate).
  const ScreenRect& response = panel.response_plot_rect();
  EXPECT_GT(brightness(shot, response, 0.9, 0.3), brightness(before, plain.response_plot_rect(), 0.9, 0.3) + 12);
  // The map: corners washed out (brighter than without), the centre as before.
  const ScreenRect& map = panel.vignette_map_rect();
  const auto at = [](const cv::Mat& image, float x, float y) {
    const testing::Rgb c = pixel(image, static_cast<int>(x), static_cast<int>(y));
    return c.r + c.g + c.b;
  };
  EXPECT_GT(at(shot, map.max.x - 3.0f, map.min.y + 3.0f), at(before, map.max.x - 3.0f, map.min.y + 3.0f) + 12);
  EXPECT_EQ(at(shot, map.centre().x, map.centre().y), at(before, map.centre().x, map.centre().y));
}

// When the fitted response's samples stop short of the top, the status row says how far they
// reach and how much brighter the images would have to be, in amber; nothing when they reach it.
TEST_F(PhotometricPanelTest, SamplesThatStopShortOfTheTopGetTheExposureAdvice) {
  Snapshot snapshot;
  auto view = estimate_view();
  view->lamp_term.clear();
  view->grey_low = 18.0;
  view->grey_high = 144.0;
  snapshot.photometric = view;
  const auto amber_pixels = [&](const cv::Mat& shot, const ScreenRect& rect) {
    int n = 0;
    for (int y = static_cast<int>(rect.min.y); y < static_cast<int>(rect.max.y); ++y)
      for (int x = static_cast<int>(rect.min.x); x < static_cast<int>(rect.max.x); ++x)
        n += near(pixel(shot, x, y), colours::state_paused, 40);
    return n;
  };
  PhotometricPanel quiet;
  const cv::Mat without = render(quiet, snapshot);
  EXPECT_TRUE(quiet.range_advice_rect().empty());

  view->range_advice = GreyRangeAdvice{144.0, 230.0, 3.1};
  PhotometricPanel advised;
  const cv::Mat with = render(advised, snapshot);
  const ScreenRect& rect = advised.range_advice_rect();
  ASSERT_FALSE(rect.empty());
  EXPECT_LT(rect.max.y, advised.response_plot_rect().min.y) << "in the status row, above the plots";
  EXPECT_GT(rect.width(), 100.0f) << "a readable part of the text";
  EXPECT_GT(amber_pixels(with, rect), 60);
  EXPECT_EQ(amber_pixels(without, rect), 0);
}

TEST_F(PhotometricPanelTest, SaysSoWhenCalibrationIsOff) {
  Snapshot snapshot;
  snapshot.photometric = std::make_shared<PhotometricView>();  // enabled = false
  PhotometricPanel panel;
  const cv::Mat shot = render(panel, snapshot);
  EXPECT_TRUE(panel.response_plot_rect().empty());
  ScreenRect middle{ImVec2(0.0f, 150.0f), ImVec2(1100.0f, 210.0f)};
  EXPECT_GT(testing::grey_stddev(shot, middle), 5.0);
}

}  // namespace
}  // namespace nirslam::ui
