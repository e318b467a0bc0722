// Per-frame metrics against independent computations: OpenCV's meanStdDev for mean and RMS
// contrast, matrix differences for the gradient energy, a direct cv::FAST call and a plain count
// for the corners and their coverage; on real frames (EuRoC, ViSP) and on constructed images.

#include <cmath>
#include <filesystem>
#include <map>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "nirslam/image/image_codec.hpp"
#include "nirslam/quality/frame_metrics.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> real_frames() {
  const fs::path euroc = fs::path(NIRSLAM_SHARED_DATA_DIR) / "euroc_v1_01_micro/mav0/cam0/data";
  return {euroc / "1403715273262142976.png", euroc / "1403715275262142976.png", euroc / "1403715277062142976.png",
          "/usr/share/visp-images-data/ViSP-images/mbt/cube/image0000.pgm",
          "/usr/share/visp-images-data/ViSP-images/mbt/cube/image0150.pgm"};
}

cv::Mat read(const fs::path& file) {
  cv::Mat image = nirslam::read_image(file);
  EXPECT_FALSE(image.empty()) << file;
  EXPECT_EQ(image.type(), CV_8UC1) << file;
  return image;
}

// Sum of squared forward differences through OpenCV matrix arithmetic (not the meter's loop).
double reference_gradient_energy(const cv::Mat& image, double full_scale) {
  cv::Mat f;
  image.convertTo(f, CV_64F, 1.0 / full_scale);
  const int h = f.rows - 1;
  const int w = f.cols - 1;
  const cv::Mat centre = f(cv::Rect(0, 0, w, h));
  const cv::Mat dx = f(cv::Rect(1, 0, w, h)) - centre;
  const cv::Mat dy = f(cv::Rect(0, 1, w, h)) - centre;
  return (cv::norm(dx, cv::NORM_L2SQR) + cv::norm(dy, cv::NORM_L2SQR)) / (static_cast<double>(w) * h);
}

TEST(FrameMetrics, MeanAndContrastMatchMeanStdDevOnRealFrames) {
  for (const fs::path& file : real_frames()) {
    SCOPED_TRACE(file.string());
    const cv::Mat image = read(file);
    cv::Scalar mean, stddev;
    cv::meanStdDev(image, mean, stddev);  // population standard deviation, as RMS contrast is defined
    const ImageQuality q = measure_quality(image, 8);
    EXPECT_NEAR(q.mean, mean[0] / 255.0, 1e-12);
    EXPECT_NEAR(q.rms_contrast, stddev[0] / 255.0, 1e-9);
    EXPECT_GT(q.rms_contrast, 0.05) << "real frames have contrast";
  }
}

TEST(FrameMetrics, SixteenBitMeanAndContrastUseTheDeclaredFullScale) {
  const cv::Mat image8 = read(real_frames().front());
  cv::Mat image12;
  image8.convertTo(image12, CV_16UC1, 16.0);  // codes 0..4080 of 4095
  cv::Scalar mean, stddev;
  cv::meanStdDev(image12, mean, stddev);
  const ImageQuality q = measure_quality(image12, 12);
  EXPECT_NEAR(q.mean, mean[0] / 4095.0, 1e-12);
  EXPECT_NEAR(q.rms_contrast, stddev[0] / 4095.0, 1e-9);
  // Codes above the declared range count as the top code.
  cv::Mat corrupt(2, 2, CV_16UC1, cv::Scalar(65535));
  EXPECT_DOUBLE_EQ(measure_quality(corrupt, 12).mean, 1.0);
  EXPECT_DOUBLE_EQ(measure_quality(corrupt, 12).rms_contrast, 0.0);
}

TEST(FrameMetrics, GradientEnergyMatchesMatrixDifferencesOnRealFrames) {
  for (const fs::path& file : real_frames()) {
    SCOPED_TRACE(file.string());
    const cv::Mat image = read(file);
    const double expected = reference_gradient_energy(image, 255.0);
    EXPECT_NEAR(gradient_energy(image, 8), expected, 1e-12 * std::max(1.0, expected));
    EXPECT_GT(expected, 1e-4);
  }
}

TEST(FrameMetrics, GradientEnergyOfDeepImagesAndKnownPatterns) {
  cv::Mat image12(97, 131, CV_16UC1);
  cv::randu(image12, 0, 4096);
  EXPECT_NEAR(gradient_energy(image12, 12), reference_gradient_energy(image12, 4095.0), 1e-12);
  // A vertical step of one full scale between two columns: one pixel in every row of the
  // (w-1) x (h-1) region sees a unit difference.
  cv::Mat step(10, 20, CV_8UC1, cv::Scalar(0));
  step.colRange(10, 20).setTo(255);
  EXPECT_NEAR(gradient_energy(step, 8), 9.0 / (9.0 * 19.0), 1e-15);
  EXPECT_DOUBLE_EQ(gradient_energy(cv::Mat(30, 40, CV_8UC1, cv::Scalar(77)), 8), 0.0);
  EXPECT_DOUBLE_EQ(gradient_energy(cv::Mat(1, 40, CV_8UC1, cv::Scalar(7)), 8), 0.0);
  // Uniform white noise over 0..255: E = 2 * 2 Var / 255^2 with Var = (256^2 - 1) / 12.
  cv::Mat noise(480, 640, CV_8UC1);
  cv::randu(noise, 0, 256);
  EXPECT_NEAR(gradient_energy(noise, 8), 4.0 * (256.0 * 256.0 - 1.0) / 12.0 / (255.0 * 255.0), 0.003);
  EXPECT_THROW(gradient_energy(cv::Mat(4, 4, CV_8UC3), 8), std::invalid_argument);
}

TEST(FrameMetrics, CornersMatchADirectFastCallAndAPlainGridCount) {
  QualityMeter meter;  // threshold 20, non-maximum suppression, 16 x 12 grid
  for (const fs::path& file : real_frames()) {
    SCOPED_TRACE(file.string());
    const cv::Mat image = read(file);
    std::vector<cv::KeyPoint> direct;
    cv::FAST(image, direct, 20, true);
    FeatureGrid grid;
    const FrameMetrics m = meter.measure(image, 8, nullptr, &grid);
    EXPECT_EQ(m.structure.feature_count, static_cast<int>(direct.size()));
    EXPECT_GT(m.structure.feature_count, 20);

    // Cells counted by hand.
    std::map<std::pair<int, int>, int> cells;
    for (const cv::KeyPoint& k : direct)
      ++cells[{static_cast<int>(k.pt.x * 16 / image.cols), static_cast<int>(k.pt.y * 12 / image.rows)}];
    EXPECT_EQ(m.structure.cells, 192);
    EXPECT_EQ(m.structure.occupied_cells, static_cast<int>(cells.size()));
    EXPECT_NEAR(m.structure.coverage, cells.size() / 192.0, 1e-15);
    double entropy = 0.0;
    for (const auto& [cell, n] : cells) {
      const double p = n / static_cast<double>(direct.size());
      entropy -= p * std::log(p);
      EXPECT_EQ(grid.counts[static_cast<std::size_t>(cell.second * 16 + cell.first)], static_cast<std::uint32_t>(n));
    }
    EXPECT_NEAR(m.structure.evenness, entropy / std::log(192.0), 1e-12);
    EXPECT_EQ(m.structure.gradient_energy, gradient_energy(image, 8));
    EXPECT_EQ(m.quality.entropy_bits, measure_quality(image, 8).entropy_bits);
  }
}

TEST(FrameMetrics, DeepFramesFindTheCornersOfTheirTopEightBits) {
  const cv::Mat image8 = read(real_frames()[3]);
  cv::Mat image16;
  image8.convertTo(image16, CV_16UC1, 256.0);
  image16 += cv::Scalar(200);  // low bits below the top eight change nothing
  QualityMeter meter;
  const FrameMetrics a = meter.measure(image8, 8);
  const FrameMetrics b = meter.measure(image16, 16);
  EXPECT_EQ(a.structure.feature_count, b.structure.feature_count);
  EXPECT_EQ(a.structure.occupied_cells, b.structure.occupied_cells);
}

TEST(FrameMetrics, EvennessOfKnownSpreads) {
  const auto points_in = [](std::initializer_list<std::pair<cv::Point2f, int>> groups) {
    std::vector<cv::KeyPoint> points;
    for (const auto& [at, n] : groups)
      for (int i = 0; i < n; ++i) points.emplace_back(at, 7.0f);
    return points;
  };
  const cv::Size size(40, 40);  // a 2 x 2 grid of 20-pixel cells
  // All in one cell: coverage 1/4, evenness 0.
  ImageStructure one = summarise_grid(count_in_grid(points_in({{{5, 5}, 9}}), size, 2, 2));
  EXPECT_EQ(one.feature_count, 9);
  EXPECT_DOUBLE_EQ(one.coverage, 0.25);
  EXPECT_DOUBLE_EQ(one.evenness, 0.0);
  // Two cells equally: ln 2 / ln 4 = 1/2.
  ImageStructure two = summarise_grid(count_in_grid(points_in({{{5, 5}, 3}, {{25, 35}, 3}}), size, 2, 2));
  EXPECT_NEAR(two.evenness, 0.5, 1e-15);
  // Every cell equally: 1.
  ImageStructure all =
      summarise_grid(count_in_grid(points_in({{{5, 5}, 2}, {{25, 5}, 2}, {{5, 25}, 2}, {{39.9f, 39.9f}, 2}}), size, 2, 2));
  EXPECT_DOUBLE_EQ(all.coverage, 1.0);
  EXPECT_NEAR(all.evenness, 1.0, 1e-15);
  // One crowded cell and three single corners: full coverage but far from even.
  ImageStructure crowded =
      summarise_grid(count_in_grid(points_in({{{5, 5}, 97}, {{25, 5}, 1}, {{5, 25}, 1}, {{25, 25}, 1}}), size, 2, 2));
  EXPECT_DOUBLE_EQ(crowded.coverage, 1.0);
  EXPECT_LT(crowded.evenness, 0.15);
  // No corners.
  ImageStructure none = summarise_grid(count_in_grid({}, size, 2, 2));
  EXPECT_EQ(none.feature_count, 0);
  EXPECT_DOUBLE_EQ(none.evenness, 0.0);
  EXPECT_THROW(count_in_grid({}, size, 0, 2), std::invalid_argument);
}

TEST(FrameMetrics, FlatAndDarkFramesHaveNoStructure) {
  QualityMeter meter;
  const FrameMetrics m = meter.measure(cv::Mat(480, 640, CV_8UC1, cv::Scalar(3)), 8);
  EXPECT_EQ(m.structure.feature_count, 0);
  EXPECT_DOUBLE_EQ(m.structure.coverage, 0.0);
  EXPECT_DOUBLE_EQ(m.structure.gradient_energy, 0.0);
  EXPECT_NEAR(m.quality.mean, 3.0 / 255.0, 1e-15);
}

TEST(FrameMetrics, MeterRejectsBadOptionsAndImages) {
  EXPECT_THROW(QualityMeter({.fast_threshold = 0}), std::invalid_argument);
  EXPECT_THROW(QualityMeter({.fast_threshold = 20, .fast_nonmax_suppression = true, .grid_cols = 0}),
               std::invalid_argument);
  QualityMeter meter;
  EXPECT_THROW(meter.measure(cv::Mat(4, 4, CV_32FC1), 8), std::invalid_argument);
  EXPECT_THROW(meter.measure(cv::Mat(4, 4, CV_8UC1), 12), std::invalid_argument);
}

}  // namespace
}  // namespace nirslam
