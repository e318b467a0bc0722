// The trajectory error heat map: a PNG of the requested size, not blank, with colour along the
// estimated path (low error blue, high error red) and none of it outside the paths and colour bar.

#include <cmath>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/test_eval_fixtures.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "nirslam/eval/trajectory_plot.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {
namespace {

using eval_testing::EvalFileTest;
using eval_testing::loop_trajectory;
namespace fs = std::filesystem;

using ErrorHeatMap = EvalFileTest;

ErrorPlotOptions sized(int width, int height) {
  ErrorPlotOptions options;
  options.width = width;
  options.height = height;
  return options;
}

// Saturated pixels: the colour map's, not the greys and black of paths, axes and text.
bool is_coloured(const cv::Vec3b& p) {
  return std::max({p[0], p[1], p[2]}) - std::min({p[0], p[1], p[2]}) > 80;
}

struct ColourCount {
  int coloured = 0;
  int blueish = 0;  // low error
  int reddish = 0;  // high error
};

ColourCount count_colours(const cv::Mat& image, const cv::Rect& region) {
  ColourCount c;
  for (int y = region.y; y < region.y + region.height; ++y)
    for (int x = region.x; x < region.x + region.width; ++x) {
      const cv::Vec3b p = image.at<cv::Vec3b>(y, x);  // BGR
      if (!is_coloured(p)) continue;
      ++c.coloured;
      if (p[0] > 150 && p[2] < 100) ++c.blueish;
      if (p[2] > 150 && p[0] < 80) ++c.reddish;
    }
  return c;
}

// A ground-truth loop and an estimate that drifts away from it more and more.
EvaluationResult drifting_loop_evaluation(const Trajectory& gt) {
  Trajectory est = gt;
  for (std::size_t k = 0; k < est.size(); ++k) {
    const double u = static_cast<double>(k) / static_cast<double>(est.size());
    const Eigen::Vector3d drift(0.4 * u * u, -0.3 * u, 0.05 * std::sin(9.0 * u));
    est.poses[k].T_world_cam =
        SE3(est.poses[k].T_world_cam.unit_quaternion(), est.poses[k].T_world_cam.translation() + drift);
  }
  return evaluate(est, gt, eval_testing::aligned_by(AlignmentMode::SE3, 50));
}

TEST_F(ErrorHeatMap, WritesAReadablePngOfTheRequestedSizeWithColourAlongThePath) {
  const Trajectory gt = loop_trajectory(600, 60.0);
  const EvaluationResult result = drifting_loop_evaluation(gt);
  ErrorPlotOptions options;
  options.width = 1000;
  options.height = 760;
  const cv::Mat image = render_evaluation_heat_map(gt.positions(), result, options);
  const fs::path file = root_ / "heat.png";
  write_png(file, image);

  const cv::Mat back = nirslam::read_image(file, nirslam::ImageReadMode::Bgr);
  ASSERT_FALSE(back.empty());
  EXPECT_EQ(back.cols, 1000);
  EXPECT_EQ(back.rows, 760);
  cv::Scalar mean, stddev;
  cv::meanStdDev(back, mean, stddev);
  EXPECT_GT(stddev[0], 10.0) << "blank image";
  EXPECT_LT(fs::file_size(file), 200u * 1024u);

  // The plot area (left three quarters): the estimate's colours, from blue (the well aligned start)
  // to red (the drifted end).
  const ColourCount path = count_colours(back, cv::Rect(0, 0, back.cols * 3 / 4, back.rows));
  EXPECT_GT(path.coloured, 2000);
  EXPECT_GT(path.blueish, 200);
  EXPECT_GT(path.reddish, 100);
  // The colour bar at the right edge holds the whole scale.
  const ColourCount bar = count_colours(back, cv::Rect(back.cols * 3 / 4, 0, back.cols / 4, back.rows));
  EXPECT_GT(bar.blueish, 100);
  EXPECT_GT(bar.reddish, 100);
  // Dark pixels (text, axes, ground truth) exist, and so does plenty of white background.
  cv::Mat grey;
  cv::cvtColor(back, grey, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero(grey < 90), 1000);
  EXPECT_GT(cv::countNonZero(grey > 250), back.total() / 2);
}

TEST_F(ErrorHeatMap, NoColourWhereThereIsNoPath) {
  // Both paths in the upper-left corner of the data: the lower-right of the plot area stays
  // without any colour-map pixel.
  std::vector<Eigen::Vector3d> gt, est;
  std::vector<double> errors;
  for (int k = 0; k < 100; ++k) {
    const double a = k * 0.02;
    gt.emplace_back(a, 1.0 - a * a / 4.0, 0.0);
    est.emplace_back(a, 1.0 - a * a / 4.0 + 0.01, 0.0);
    errors.push_back(0.01 * k);
  }
  gt.emplace_back(2.0, -1.0, 0.0);  // stretches the view down and right: an empty corner
  const cv::Mat image = render_error_heat_map(gt, est, errors, sized(800, 600));
  EXPECT_EQ(image.cols, 800);
  EXPECT_EQ(image.rows, 600);
  EXPECT_GT(count_colours(image, cv::Rect(0, 0, 560, 600)).coloured, 300);
}

TEST_F(ErrorHeatMap, RejectsBadArgumentsAndUnwritableFiles) {
  const std::vector<Eigen::Vector3d> gt{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}};
  EXPECT_THROW(render_error_heat_map(gt, gt, {0.1, 0.2}), std::invalid_argument);
  EXPECT_THROW(render_error_heat_map(gt, {}, {}), std::invalid_argument);
  EXPECT_THROW(render_error_heat_map(gt, gt, {0, 0, 0}, sized(100, 100)), std::invalid_argument);
  // All-zero errors and a single pose still render.
  EXPECT_EQ(render_error_heat_map(gt, gt, {0, 0, 0}).cols, 1200);
  EXPECT_EQ(render_error_heat_map({}, {gt[0]}, {0.5}).rows, 900);
  const cv::Mat image = render_error_heat_map(gt, gt, {0, 0.1, 0.2});
  const fs::path bad = root_ / "missing-folder" / "heat.png";
  try {
    write_png(bad, image);
    FAIL() << "write into a missing folder succeeded";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), bad);
  }
}

}  // namespace
}  // namespace nirslam
