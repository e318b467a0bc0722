#include <filesystem>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "nirslam/photometric/calibration_output.hpp"

namespace nirslam {
namespace {

nlohmann::json written_json(const PhotometricEstimate& estimate, const std::filesystem::path& dir) {
  std::filesystem::remove_all(dir);
  CalibrationOutputInfo info;
  info.width = 64;
  info.height = 48;
  write_calibration_output(dir, estimate, {}, info, std::nullopt);
  std::ifstream file(dir / "calibration.json");
  nlohmann::json j = nlohmann::json::parse(file);
  std::filesystem::remove_all(dir);
  return j;
}

// With the halo factor as a lens vignette times the lamp's beam, calibration.json names the lens
// beside the exponent: V_lens cos(alpha)^m is what the odometry applies, and a reader
// (tests/tools/colit_calibration_errors.py) can evaluate it instead of the sextic "vignette".
TEST(CalibrationJson, NamesTheBeamsLensBesideItsExponent) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "nirslam_calibration_json_test";
  PhotometricEstimate estimate;
  const nlohmann::json plain = written_json(estimate, dir);
  EXPECT_TRUE(plain.at("lamp_beam_exponent").is_null());
  EXPECT_TRUE(plain.at("lamp_beam_lens").is_null());

  estimate.beam_exponent = 5.7;
  estimate.beam_lens = VignetteModel{Eigen::Vector3d(-0.35, 0.10, -0.05)};
  const nlohmann::json beam = written_json(estimate, dir);
  EXPECT_DOUBLE_EQ(beam.at("lamp_beam_exponent").get<double>(), 5.7);
  const std::vector<double> lens = beam.at("lamp_beam_lens").get<std::vector<double>>();
  ASSERT_EQ(lens.size(), 3u);
  EXPECT_DOUBLE_EQ(lens[0], -0.35);
  EXPECT_DOUBLE_EQ(lens[1], 0.10);
  EXPECT_DOUBLE_EQ(lens[2], -0.05);
}

}  // namespace
}  // namespace nirslam
