// The 3-D view rendered headless from hand-made trajectories: the path shows in its colours where
// its poses project, the error colouring follows the per-pose error, map points are drawn, and the
// view is blank-free but honest when there is no odometry.

#include <cmath>
#include <memory>
#include <numbers>

#include <gtest/gtest.h>

#include "ui/colour_maps.hpp"
#include "ui/gl/shader.hpp"
#include "ui/panels/trajectory_panel.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using testing::full_window;
using testing::near;
using testing::pixel;

// A circle of `n` poses of radius 2 m in the z = 0 plane (z up), cameras looking along the path
// (their -y axis up), keyframes every 10th pose, a ring of map points outside at radius 3 m.
std::shared_ptr<TrajectoryView> circle_view(int n, bool with_error) {
  auto view = std::make_shared<TrajectoryView>();
  view->enabled = true;
  view->tracking = "tracking";
  auto points = std::make_shared<std::vector<MapPointSample>>();
  for (int i = 0; i < n; ++i) {
    const double a = 1.8 * std::numbers::pi * i / (n - 1);
    PoseSample p;
    p.frame_index = i;
    p.timestamp_s = i / 30.0;
    p.position = Eigen::Vector3f(2.0f * std::cos(a), 2.0f * std::sin(a), 0.0f);
    // Camera axes: z forward along the tangent, y down = -world z, x = y cross z.
    const Eigen::Vector3f z(-std::sin(a), std::cos(a), 0.0f);
    const Eigen::Vector3f y(0.0f, 0.0f, -1.0f);
    Eigen::Matrix3f R;
    R.col(0) = y.cross(z);
    R.col(1) = y;
    R.col(2) = z;
    p.rotation = Eigen::Quaternionf(R);
    p.error_m = with_error ? static_cast<float>(0.1 * i / (n - 1)) : -1.0f;
    view->poses.push_back(p);
    if (i % 10 == 0) view->keyframes.push_back(p);
  }
  for (int i = 0; i < 2000; ++i) {
    const double a = 2.0 * std::numbers::pi * i / 2000.0;
    points->push_back({Eigen::Vector3f(3.0f * std::cos(a), 3.0f * std::sin(a), 0.5f * std::sin(7.0 * a)), 200.0f, i % 2 == 0});
  }
  view->points = points;
  view->current = view->poses.back();
  view->path_length = 2.0 * 1.8 * std::numbers::pi * 2.0;
  view->aligned_to_ground_truth = with_error;
  if (with_error) view->ate_rmse_m = 0.05;
  return view;
}

class TrajectoryPanelTest : public testing::HeadlessGlTest {
protected:
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ui_ = std::make_unique<OffscreenUi>(800, 600);
    panel_ = std::make_unique<TrajectoryPanel>(gl::find_shader_dir());
  }
  void TearDown() override {
    panel_.reset();
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  cv::Mat render(const Snapshot& snapshot) {
    for (int i = 0; i < 2; ++i) ui_->frame([&] { full_window([&] { panel_->draw(snapshot); }); });
    cv::Mat shot = ui_->read_rgba();
    testing::save_if_requested(shot, ::testing::UnitTest::GetInstance()->current_test_info()->name());
    return shot;
  }
  // Pixels within `radius` of p with a colour within `tolerance` of `colour`.
  static int colour_near(const cv::Mat& shot, ImVec2 p, ImU32 colour, int radius, int tolerance) {
    int count = 0;
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx) {
        const int x = static_cast<int>(p.x) + dx;
        const int y = static_cast<int>(p.y) + dy;
        if (x >= 0 && y >= 0 && x < shot.cols && y < shot.rows) count += near(pixel(shot, x, y), colour, tolerance) ? 1 : 0;
      }
    return count;
  }
  std::unique_ptr<OffscreenUi> ui_;
  std::unique_ptr<TrajectoryPanel> panel_;
};

TEST_F(TrajectoryPanelTest, PathIsDrawnInTimeColoursWherePosesProject) {
  Snapshot snapshot;
  const auto view = circle_view(120, false);
  snapshot.trajectory = view;
  panel_->colouring = TrajectoryPanel::Colouring::Time;
  panel_->show_points = false;
  const cv::Mat shot = render(snapshot);
  ASSERT_FALSE(panel_->view_rect().empty());
  EXPECT_FALSE(panel_->colouring_by_error());
  // Every 10th pose (skipping the keyframe frusta at multiples of 10, and the current camera)
  // has a dot of its time colour where it projects.
  int found = 0;
  int checked = 0;
  for (int i = 5; i < 110; i += 10) {
    const auto p = panel_->project(view->poses[i].position);
    ASSERT_TRUE(p.has_value());
    ASSERT_TRUE(panel_->view_rect().contains(*p)) << i;
    ++checked;
    found += colour_near(shot, *p, time_colour(static_cast<float>(i) / 119.0f), 3, 24) > 0 ? 1 : 0;
  }
  EXPECT_EQ(found, checked);
  // The start and the end of the path differ in colour (blue vs red end of the ramp).
  const testing::Rgb start = testing::rgb_of(time_colour(0.0f));
  const testing::Rgb end = testing::rgb_of(time_colour(1.0f));
  EXPECT_GT(std::abs(start.r - end.r) + std::abs(start.b - end.b), 150);
}

TEST_F(TrajectoryPanelTest, ErrorColouringFollowsThePerPoseError) {
  Snapshot snapshot;
  const auto view = circle_view(120, true);
  snapshot.trajectory = view;
  panel_->show_points = false;
  const cv::Mat shot = render(snapshot);
  EXPECT_TRUE(panel_->colouring_by_error());
  // Small error (early poses) in green, large error (late poses) in red.
  const auto early = panel_->project(view->poses[5].position);
  const auto late = panel_->project(view->poses[115].position);
  ASSERT_TRUE(early && late);
  EXPECT_GT(colour_near(shot, *early, error_colour(5.0f / 119.0f), 3, 24), 0);
  EXPECT_GT(colour_near(shot, *late, error_colour(115.0f / 119.0f), 3, 24), 0);
  EXPECT_EQ(colour_near(shot, *early, error_colour(1.0f), 3, 24), 0);
}

TEST_F(TrajectoryPanelTest, MapPointsAreDrawn) {
  Snapshot snapshot;
  const auto view = circle_view(60, false);
  snapshot.trajectory = view;
  panel_->show_points = true;
  panel_->point_size = 3.0f;
  const cv::Mat shot_with = render(snapshot);
  int lit = 0;
  int inside = 0;
  for (std::size_t i = 0; i < view->points->size(); i += 50) {
    const auto p = panel_->project((*view->points)[i].position);
    if (!p || !panel_->view_rect().contains(*p)) continue;
    ++inside;
    const testing::Rgb c = pixel(shot_with, *p);
    lit += (c.r + c.g + c.b) > 3 * 90 ? 1 : 0;  // points are bright against the dark background
  }
  ASSERT_GT(inside, 10);
  EXPECT_GT(lit, inside * 7 / 10);
}

TEST_F(TrajectoryPanelTest, SaysWhyWhenThereIsNoPose) {
  Snapshot snapshot;
  auto view = std::make_shared<TrajectoryView>();
  view->enabled = true;
  view->tracking = "initialising";
  snapshot.trajectory = view;
  const cv::Mat shot = render(snapshot);
  // The message is drawn in the middle of the view: text pixels there.
  ScreenRect middle = panel_->view_rect();
  middle.min.y = middle.centre().y - 30.0f;
  middle.max.y = middle.centre().y + 30.0f;
  EXPECT_GT(testing::grey_stddev(shot, middle), 5.0);
}

}  // namespace
}  // namespace nirslam::ui
