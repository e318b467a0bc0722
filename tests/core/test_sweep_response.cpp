// The power-sweep wizard's response: which frames are kept, the fit's refusals, the files written.

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "nirslam/illumination/sweep_response.hpp"

namespace nirslam {
namespace {

Frame frame_of(cv::Mat image, std::optional<double> exposure_ms, std::optional<double> gain = std::nullopt) {
  Frame frame;
  frame.image = std::move(image);
  frame.bit_depth = frame.image.depth() == CV_16U ? 16 : 8;
  frame.exposure_ms = exposure_ms;
  frame.gain = gain;
  return frame;
}

TEST(SweepShots, KeepsTwoFramesAPowerWithTheirExposureOnTheEightBitScale) {
  SweepShots shots;
  const cv::Mat grey(8, 8, CV_8UC1, cv::Scalar(100));
  for (int k = 0; k < 3; ++k) shots.add(20.0, frame_of(grey, 4.0, 2.0));
  shots.add(40.0, frame_of(cv::Mat(8, 8, CV_16UC1, cv::Scalar(257 * 200)), 4.0));
  shots.add(60.0, frame_of(grey, std::nullopt));
  shots.add(80.0, frame_of(cv::Mat(8, 8, CV_8UC3, cv::Scalar(1, 2, 3)), 4.0));
  shots.add(80.0, frame_of(cv::Mat(8, 8, CV_32FC1, cv::Scalar(0.5)), 4.0));
  ASSERT_EQ(shots.shots().size(), 3u) << "two at 20 W, one at 40 W, none without an exposure or grey image";
  EXPECT_DOUBLE_EQ(shots.shots()[0].exposure, 8.0) << "exposure time x gain";
  EXPECT_EQ(shots.shots()[2].grey.type(), CV_8UC1);
  EXPECT_EQ(shots.shots()[2].grey.at<std::uint8_t>(3, 3), 200);
  EXPECT_EQ(shots.missing_exposure(), 1);
  EXPECT_EQ(shots.unusable_images(), 2) << "a colour and a floating-point frame";
  shots.clear();
  EXPECT_TRUE(shots.shots().empty());
  EXPECT_EQ(shots.missing_exposure(), 0);
  EXPECT_EQ(shots.unusable_images(), 0);
}

TEST(SweepResponse, TooFewPowersOrADegenerateFitFailWithAReason) {
  std::vector<SweepShot> shots;
  const cv::Mat grey(64, 64, CV_8UC1, cv::Scalar(100));
  for (const double power : {0.0, 10.0, 20.0}) shots.push_back({power, 4.0, grey});
  const SweepResponse two = fit_sweep_response(shots);
  EXPECT_EQ(two.state, SweepResponse::State::Failed);
  EXPECT_NE(two.reason.find("2 lamp powers above 0 W"), std::string::npos) << two.reason;
  shots.push_back({40.0, 4.0, cv::Mat(64, 64, CV_8UC1, cv::Scalar(255))});
  const SweepResponse flat = fit_sweep_response(shots);  // flat or saturated images: nothing to fit
  EXPECT_EQ(flat.state, SweepResponse::State::Failed);
  EXPECT_FALSE(flat.reason.empty());
}

TEST(SweepResponse, WritesPcalibAndItsSummaryAndNamesAFolderItCannotWrite) {
  const auto root = std::filesystem::temp_directory_path() / "nirslam_sweep_response_files";
  std::filesystem::remove_all(root);
  SweepResponse response;
  response.state = SweepResponse::State::Done;
  response.response = ResponseModel::from_preset(ResponsePreset::Gamma);
  response.powers_w = {10.0, 20.0, 40.0};
  response.residual_rms_grey = 0.4;
  write_sweep_response(response, root / "cal");
  const std::vector<double> G = read_pcalib(root / "cal" / "pcalib.txt");
  ASSERT_EQ(G.size(), 256u);
  EXPECT_NEAR(G[128], response.response.inverse_table(256)[128], 1e-6);
  std::ifstream in(root / "cal" / "sweep_response.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  EXPECT_EQ(summary.at("powers_w").size(), 3u);
  EXPECT_DOUBLE_EQ(summary.at("residual_rms_grey").get<double>(), 0.4);
  std::ofstream(root / "a_file") << "x";
  try {
    write_sweep_response(response, root / "a_file" / "cal");
    FAIL() << "wrote under a file";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("a_file"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace nirslam
