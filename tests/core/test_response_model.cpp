// The shared photometric model: the response basis and its presets, the vignetting polynomial,
// and DSO's pcalib.txt / vignette.png files.

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

constexpr ResponsePreset kPresets[] = {ResponsePreset::Linear, ResponsePreset::Gamma, ResponsePreset::Log,
                                       ResponsePreset::Filmic};

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("nirslam_response_" + name + "_" + std::to_string(std::random_device{}()));
  fs::create_directories(dir);
  return dir;
}

TEST(ResponseModel, BasisEndsAtZeroAndOneForAnyCoefficients) {
  const ResponseModel f(Eigen::Vector4d(0.3, -0.2, 0.1, 0.05));
  EXPECT_DOUBLE_EQ(f(0.0), 0.0);
  EXPECT_DOUBLE_EQ(f(1.0), 1.0);
  for (int k = 1; k <= 4; ++k) {
    EXPECT_DOUBLE_EQ(ResponseModel::basis(k, 0.0), 0.0);
    EXPECT_NEAR(ResponseModel::basis(k, 1.0), 0.0, 1e-15);
  }
  // f is linear in c: f = h0 + sum c_k h_k.
  const double X = 0.37;
  double sum = ResponseModel::basis(0, X);
  for (int k = 1; k <= 4; ++k) sum += f.coefficients()[k - 1] * ResponseModel::basis(k, X);
  EXPECT_NEAR(f(X), sum, 1e-15);
}

TEST(ResponseModel, LinearPresetIsExactlyLinear) {
  const ResponseModel f = ResponseModel::from_preset(ResponsePreset::Linear);
  for (double X = 0.0; X <= 1.0; X += 0.01) EXPECT_NEAR(f(X), X, 1e-12);
  EXPECT_NEAR(f.derivative(0.0), 1.0, 1e-4);
}

TEST(ResponseModel, PresetsAreMonotonicAndFollowTheirReferenceCurves) {
  // The documented largest deviations, in grey levels of 255.
  const double tolerance[] = {1e-9, 0.7, 1.35, 0.15};
  for (std::size_t i = 0; i < 4; ++i) {
    const ResponseModel f = ResponseModel::from_preset(kPresets[i]);
    EXPECT_TRUE(f.is_monotonic()) << to_string(kPresets[i]);
    double worst = 0.0;
    for (int k = 0; k <= 10000; ++k) {
      const double X = k / 10000.0;
      worst = std::max(worst, 255.0 * std::abs(f(X) - response_preset_reference(kPresets[i], X)));
    }
    EXPECT_LT(worst, tolerance[i]) << to_string(kPresets[i]);
    EXPECT_EQ(parse_response_preset(to_string(kPresets[i])), kPresets[i]);
  }
  EXPECT_FALSE(parse_response_preset("sigmoid"));
}

TEST(ResponseModel, InverseAndDerivativeAgreeWithTheCurve) {
  for (const ResponsePreset p : kPresets) {
    const ResponseModel f = ResponseModel::from_preset(p);
    for (double X = 0.01; X < 1.0; X += 0.0137) {
      EXPECT_NEAR(f.inverse(f(X)), X, 1e-12) << to_string(p);
      const double h = 1e-6;
      EXPECT_NEAR(f.derivative(X), (f(X + h) - f(X - h)) / (2 * h), 1e-4 * std::max(1.0, f.derivative(X))) << to_string(p);
    }
  }
  EXPECT_FALSE(ResponseModel(Eigen::Vector4d(-3.0, 0.0, 0.0, 0.0)).is_monotonic());
}

TEST(ResponseModel, InverseTableSpansTheGreyRangeAndIncreases) {
  const std::vector<double> G = ResponseModel::from_preset(ResponsePreset::Gamma).inverse_table(256);
  ASSERT_EQ(G.size(), 256u);
  EXPECT_NEAR(G.front(), 0.0, 1e-12);
  EXPECT_NEAR(G.back(), 255.0, 1e-9);
  for (std::size_t i = 1; i < G.size(); ++i) EXPECT_GT(G[i], G[i - 1]);
  // Gamma 2.2: grey 128 comes from about (128/255)^2.2 of full exposure.
  EXPECT_NEAR(G[128] / 255.0, std::pow(128.0 / 255.0, 2.2), 0.01);
}

TEST(VignetteModel, IsOneAtTheCentreAndReachesTheCornersAtRadiusOne) {
  const VignetteModel v{Eigen::Vector3d(-0.35, 0.1, -0.05)};
  EXPECT_TRUE(v.is_plausible());
  EXPECT_DOUBLE_EQ(v(0.0), 1.0);
  EXPECT_NEAR(v(1.0), 0.7, 1e-12);
  EXPECT_NEAR(VignetteModel::radius(0, 0, 640, 480), 1.0, 1e-12);
  EXPECT_NEAR(VignetteModel::radius(639, 479, 640, 480), 1.0, 1e-12);
  EXPECT_NEAR(VignetteModel::radius(319.5, 239.5, 640, 480), 0.0, 1e-12);
  const cv::Mat map = v.render(640, 480);
  EXPECT_NEAR(map.at<float>(0, 0), 0.7f, 1e-6);
  // The map (from r^2 directly) is V(radius) at every pixel, also for odd sizes.
  const cv::Mat odd = v.render(97, 61);
  for (int y = 0; y < odd.rows; ++y)
    for (int x = 0; x < odd.cols; ++x) ASSERT_NEAR(odd.at<float>(y, x), v(VignetteModel::radius(x, y, 97, 61)), 1e-6) << x << "," << y;
  EXPECT_FALSE(VignetteModel{Eigen::Vector3d(0.5, 0.0, 0.0)}.is_plausible());  // brighter at the rim
  EXPECT_FALSE(VignetteModel{Eigen::Vector3d(-1.5, 0.0, 0.0)}.is_plausible()); // negative
}

TEST(PhotometricFiles, PcalibRoundTrips) {
  const fs::path dir = fresh_dir("pcalib");
  const std::vector<double> G = ResponseModel::from_preset(ResponsePreset::Filmic).inverse_table(256);
  write_pcalib(dir / "pcalib.txt", G);
  const std::vector<double> back = read_pcalib(dir / "pcalib.txt");
  ASSERT_EQ(back.size(), 256u);
  for (std::size_t i = 0; i < G.size(); ++i) EXPECT_NEAR(back[i], G[i], 1e-6 * std::max(1.0, G[i]));
  // One line, as DSO reads it.
  std::ifstream in(dir / "pcalib.txt");
  std::string line;
  int lines = 0;
  while (std::getline(in, line)) ++lines;
  EXPECT_EQ(lines, 1);
  fs::remove_all(dir);
}

TEST(PhotometricFiles, BadPcalibFilesAreNamed) {
  const fs::path dir = fresh_dir("badpcalib");
  EXPECT_THROW(read_pcalib(dir / "missing.txt"), InputError);
  {
    std::ofstream(dir / "short.txt") << "0 1 2 3\n";
  }
  try {
    read_pcalib(dir / "short.txt");
    FAIL() << "a 4-value file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("short.txt"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("256"), std::string::npos);
  }
  {
    std::ofstream out(dir / "flat.txt");
    for (int i = 0; i < 256; ++i) out << (i == 100 ? 99 : i) << ' ';
  }
  EXPECT_THROW(read_pcalib(dir / "flat.txt"), InputError);
  {
    std::ofstream out(dir / "word.txt");
    out << "0 1 x";
  }
  EXPECT_THROW(read_pcalib(dir / "word.txt"), InputError);
  fs::remove_all(dir);
}

TEST(PhotometricFiles, VignettePngRoundTripsNormalisedByItsMaximum) {
  const fs::path dir = fresh_dir("vignette");
  const cv::Mat map = VignetteModel{Eigen::Vector3d(-0.4, 0.05, 0.0)}.render(160, 120);
  write_vignette_png(dir / "vignette.png", map);
  const cv::Mat raw = nirslam::read_image(dir / "vignette.png");
  EXPECT_EQ(raw.type(), CV_16UC1);
  const cv::Mat back = read_vignette_png(dir / "vignette.png");
  double max_value = 0.0;
  cv::minMaxLoc(map, nullptr, &max_value);
  EXPECT_LT(cv::norm(back, map / max_value, cv::NORM_INF), 1.0 / 65535.0 + 1e-6);
  EXPECT_THROW(read_vignette_png(dir / "none.png"), InputError);
  fs::remove_all(dir);
}

TEST(PhotometricFiles, WriteFailureNamesTheFile) {
  const fs::path dir = fresh_dir("full");
  fs::create_symlink("/dev/full", dir / "pcalib.txt");
  try {
    write_pcalib(dir / "pcalib.txt", std::vector<double>(256, 1.0));
    FAIL() << "writing to a full disk succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("pcalib.txt"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace nirslam
