// A photometric calibration given as DSO files (given_calibration.hpp): the fits recover the
// model the files were written from, files the model cannot follow are refused by name, and the
// pipeline holds the given model instead of estimating one.

#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/photometric/beam_halo.hpp"
#include "nirslam/photometric/given_calibration.hpp"
#include "nirslam/pipeline/slam_pipeline.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

constexpr int kVignetteWidth = 160, kVignetteHeight = 120;

fs::path fresh_calibration_folder(const std::string& name) {
  const fs::path folder = fs::temp_directory_path() /
                          ("nirslam_given_" + name + "_" + std::to_string(std::random_device{}()));
  fs::create_directories(folder);
  return folder;
}

// The files `nirslam simulate` and `nirslam calibrate` write for this model.
fs::path write_dso_files(const std::string& name, const ResponseModel& response, const VignetteModel& vignette) {
  const fs::path folder = fresh_calibration_folder(name);
  write_pcalib(folder / "pcalib.txt", response.inverse_table(256));
  write_vignette_png(folder / "vignette.png", vignette.render(kVignetteWidth, kVignetteHeight));
  return folder;
}

TEST(GivenCalibration, ResponseFitRecoversEveryPreset) {
  for (ResponsePreset preset : {ResponsePreset::Linear, ResponsePreset::Gamma, ResponsePreset::Log, ResponsePreset::Filmic}) {
    const ResponseModel truth = ResponseModel::from_preset(preset);
    std::vector<double> table = truth.inverse_table(256);
    for (double& g : table) g *= 4.0;  // pcalib.txt's scale is free (DSO normalises by the top value)
    const ResponseFit fit = fit_response_to_inverse_table(table);
    EXPECT_LT((fit.response.coefficients() - truth.coefficients()).norm(), 1e-6) << to_string(preset);
    EXPECT_LT(fit.max_grey, 0.01) << to_string(preset);
  }
}

TEST(GivenCalibration, ResponseFitOfACurveOutsideTheBasisSaysItsError) {
  // A pure gamma 2.2 curve is not one of the basis's curves: close, with the error said.
  std::vector<double> table(256);
  for (int i = 0; i < 256; ++i) table[static_cast<std::size_t>(i)] = 255.0 * std::pow(i / 255.0, 2.2);
  const ResponseFit fit = fit_response_to_inverse_table(table);
  EXPECT_TRUE(fit.response.is_monotonic());
  EXPECT_GT(fit.rms_grey, 0.0);
  EXPECT_LT(fit.rms_grey, 1.0);
  EXPECT_LT(std::abs(255.0 * fit.response.inverse(128.0 / 255.0) - table[128]), 1.5);
}

TEST(GivenCalibration, VignetteFitRecoversTheModelUpToScale) {
  const VignetteModel truth{Eigen::Vector3d(-0.35, 0.12, -0.08)};
  cv::Mat image = truth.render(kVignetteWidth, kVignetteHeight) * 0.7;
  const VignetteFit fit = fit_vignette_to_image(image);
  EXPECT_LT((fit.vignette.v - truth.v).norm(), 1e-4) << fit.vignette.v.transpose();
  EXPECT_LT(fit.max, 1e-4);  // the image is float
}

TEST(GivenCalibration, RealEurocEstimateFits) {
  // DSO files made by others for the EuRoC cameras (online photometric calibration, not ground
  // truth): a response close to linear, which the free fit bends below 0 near black.
  const fs::path folder = fs::path(NIRSLAM_SHARED_DATA_DIR) / "euroc_v1_01_micro" / "photometric_estimate";
  const GivenPhotometricCalibration given = read_given_calibration(folder, 752, 480);
  EXPECT_TRUE(given.response.is_monotonic());
  ASSERT_TRUE(given.response_fit);
  EXPECT_LT(given.response_fit->rms_grey, 1.0);
  EXPECT_LT(given.response_fit->max_grey, 2.5);
  ASSERT_TRUE(given.vignette_fit);
  EXPECT_LT(given.vignette_fit->rms, 0.001);
  EXPECT_LT(given.vignette(1.0), 0.85) << "the corners are darker";
}

TEST(GivenCalibration, FolderRoundTripsAndSaysWhatItRead) {
  const ResponseModel response = ResponseModel::from_preset(ResponsePreset::Log);
  const VignetteModel vignette{Eigen::Vector3d(-0.3, 0.05, -0.02)};
  const fs::path folder = write_dso_files("roundtrip", response, vignette);
  const GivenPhotometricCalibration given = read_given_calibration(folder, kVignetteWidth, kVignetteHeight);
  // pcalib.txt holds G to a few decimals and vignette.png V to 16 bits: close, not exact.
  EXPECT_LT((given.response.coefficients() - response.coefficients()).norm(), 1e-3);
  EXPECT_LT((given.vignette.v - vignette.v).norm(), 2e-3);
  ASSERT_TRUE(given.vignette_fit);
  EXPECT_NE(given.description.find("pcalib.txt"), std::string::npos) << given.description;
  EXPECT_NE(given.description.find("vignette.png"), std::string::npos) << given.description;

  // Without vignette.png: no vignetting, and the description says so.
  fs::remove(folder / "vignette.png");
  const GivenPhotometricCalibration response_only = read_given_calibration(folder, kVignetteWidth, kVignetteHeight);
  EXPECT_EQ(response_only.vignette.v, Eigen::Vector3d::Zero());
  EXPECT_NE(response_only.description.find("no vignetting"), std::string::npos) << response_only.description;
  fs::remove_all(folder);
}

TEST(GivenCalibration, EachPartReadsItsOwnFile) {
  const ResponseModel response = ResponseModel::from_preset(ResponsePreset::Log);
  const VignetteModel vignette{Eigen::Vector3d(-0.3, 0.05, -0.02)};
  const fs::path folder = write_dso_files("parts", response, vignette);
  fs::remove(folder / "vignette.png");
  const GivenPhotometricCalibration response_part =
      read_given_calibration(folder, kVignetteWidth, kVignetteHeight, GivenCalibrationParts::Response);
  EXPECT_LT((response_part.response.coefficients() - response.coefficients()).norm(), 1e-3);
  EXPECT_FALSE(response_part.vignette_fit);
  EXPECT_EQ(response_part.description, response_part.response_description);
  EXPECT_NE(response_part.description.find("pcalib.txt"), std::string::npos) << response_part.description;

  // A lens vignette alone: no pcalib.txt needed, the response left at the gamma start.
  write_vignette_png(folder / "vignette.png", vignette.render(kVignetteWidth, kVignetteHeight));
  fs::remove(folder / "pcalib.txt");
  const GivenPhotometricCalibration vignette_part =
      read_given_calibration(folder, kVignetteWidth, kVignetteHeight, GivenCalibrationParts::Vignette);
  EXPECT_LT((vignette_part.vignette.v - vignette.v).norm(), 2e-3);
  EXPECT_FALSE(vignette_part.response_fit);
  EXPECT_EQ(vignette_part.response.coefficients(), ResponseModel::from_preset(ResponsePreset::Gamma).coefficients());
  EXPECT_EQ(vignette_part.description.find("pcalib.txt"), std::string::npos) << vignette_part.description;

  // The vignette to hold must be there.
  fs::remove(folder / "vignette.png");
  try {
    read_given_calibration(folder, kVignetteWidth, kVignetteHeight, GivenCalibrationParts::Vignette);
    FAIL() << "no vignette.png";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vignette.png"), std::string::npos) << e.what();
  }
  EXPECT_EQ(given_calibration_parts_from_string("response"), GivenCalibrationParts::Response);
  EXPECT_EQ(given_calibration_parts_from_string("lens"), std::nullopt);
  fs::remove_all(folder);
}

std::string given_calibration_error(const fs::path& folder, int width = kVignetteWidth, int height = kVignetteHeight) {
  try {
    read_given_calibration(folder, width, height);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(GivenCalibration, BadFilesAreRefusedByName) {
  const fs::path folder = write_dso_files("bad", ResponseModel::from_preset(ResponsePreset::Gamma), VignetteModel{});
  // The vignette of another camera.
  std::string e = given_calibration_error(folder, 320, 240);
  EXPECT_NE(e.find("vignette.png"), std::string::npos) << e;
  EXPECT_NE(e.find("160x120"), std::string::npos) << e;
  // A response the model cannot follow (a hard knee: linear, then flat at the top).
  {
    std::ofstream out(folder / "pcalib.txt");
    for (int i = 0; i < 256; ++i) out << (i < 200 ? i * 0.2 : 40.0 + (i - 200) * 3.9) << ' ';
  }
  e = given_calibration_error(folder);
  EXPECT_NE(e.find("pcalib.txt"), std::string::npos) << e;
  EXPECT_NE(e.find("response model"), std::string::npos) << e;
  // A vignette the radial model cannot follow (one bright quadrant).
  write_pcalib(folder / "pcalib.txt", ResponseModel::from_preset(ResponsePreset::Gamma).inverse_table(256));
  cv::Mat lopsided(kVignetteHeight, kVignetteWidth, CV_32FC1, cv::Scalar(0.6f));
  lopsided(cv::Rect(0, 0, kVignetteWidth / 2, kVignetteHeight / 2)).setTo(1.0f);
  write_vignette_png(folder / "vignette.png", lopsided);
  e = given_calibration_error(folder);
  EXPECT_NE(e.find("vignette.png"), std::string::npos) << e;
  EXPECT_NE(e.find("radial vignette model"), std::string::npos) << e;
  // No pcalib.txt, and not a folder at all.
  fs::remove(folder / "pcalib.txt");
  e = given_calibration_error(folder);
  EXPECT_NE(e.find("pcalib.txt"), std::string::npos) << e;
  EXPECT_NE(e.find("missing"), std::string::npos) << e;
  e = given_calibration_error(folder / "no_such_folder");
  EXPECT_NE(e.find("no_such_folder"), std::string::npos) << e;
  fs::remove_all(folder);
}

// Frames of a static noise texture with a small brightness ramp (the pipeline tests have no camera,
// so no odometry: what they check is the calibration's model).
void feed_noise_frames(SlamPipeline& pipeline, int count, const std::function<void(int, const Frame&, const PipelineFrameResult&)>& check) {
  cv::Mat texture(kVignetteHeight, kVignetteWidth, CV_8UC1);
  cv::randu(texture, 40, 200);
  for (int i = 0; i < count; ++i) {
    Frame frame;
    texture.convertTo(frame.image, CV_8UC1, 1.0, 2.0 * (i % 3));
    frame.index = i;
    frame.timestamp_s = i / 30.0;
    frame.exposure_ms = 10.0 + i;
    frame.name = "frame" + std::to_string(i);
    const PipelineFrameResult result = pipeline.process(frame);
    ASSERT_FALSE(result.corrected.empty());
    check(i, frame, result);
  }
}

PipelineOptions calibrated_with_files(const fs::path& folder) {
  PipelineOptions options;
  options.mode = PipelineMode::Calibrated;
  options.calibration.background_thread = false;
  options.given_calibration_folder = folder;
  return options;
}

TEST(GivenCalibration, PipelineHoldsAGivenPartAndEstimatesTheRest) {
  const ResponseModel response = ResponseModel::from_preset(ResponsePreset::Filmic);
  const VignetteModel vignette{Eigen::Vector3d(-0.25, 0.0, 0.0)};
  const fs::path folder = write_dso_files("pipeline_parts", response, vignette);
  PipelineOptions options = calibrated_with_files(folder);

  options.given_calibration_holds = GivenCalibrationParts::Response;
  {
    SlamPipeline pipeline(options, nullptr);
    ASSERT_NE(pipeline.calibration(), nullptr);
    feed_noise_frames(pipeline, 6, [](int, const Frame&, const PipelineFrameResult&) {});
    const auto estimate = pipeline.calibration()->estimate();
    EXPECT_EQ(estimate->ambiguity, AmbiguityResolution::Given) << "the file's response fixes gamma and scale";
    EXPECT_NE(estimate->ambiguity_detail.find("response given"), std::string::npos) << estimate->ambiguity_detail;
    EXPECT_EQ(estimate->status.find("held (no online estimation)"), std::string::npos) << estimate->status;
    EXPECT_LT((estimate->response.coefficients() - response.coefficients()).norm(), 1e-3);
    EXPECT_EQ(estimate->vignette.v, Eigen::Vector3d::Zero()) << "the vignette starts where it starts without files";
  }
  options.given_calibration_holds = GivenCalibrationParts::Vignette;
  {
    SlamPipeline pipeline(options, nullptr);
    feed_noise_frames(pipeline, 6, [](int, const Frame&, const PipelineFrameResult&) {});
    const auto estimate = pipeline.calibration()->estimate();
    EXPECT_NE(estimate->ambiguity, AmbiguityResolution::Given) << "the response is estimated";
    EXPECT_NE(estimate->ambiguity_detail.find("lens vignette given"), std::string::npos) << estimate->ambiguity_detail;
    EXPECT_LT((estimate->vignette.v - vignette.v).norm(), 2e-3);
  }
  fs::remove_all(folder);
}

// The illuminated mode over a held lens vignette (written as DSO files) with the beam estimated,
// on a 75-degree camera, as the beam tests below share it.
struct LampOverLensVignette {
  VignetteModel lens{Eigen::Vector3d(-0.25, 0.0, 0.0)};
  fs::path folder;
  std::shared_ptr<PinholeCamera> camera;
  PipelineOptions options;

  explicit LampOverLensVignette(const std::string& name)
      : folder(write_dso_files(name, ResponseModel::from_preset(ResponsePreset::Gamma), lens)) {
    const double f = 80.0 / std::tan(37.5 * M_PI / 180.0);
    camera = std::make_shared<PinholeCamera>(kVignetteWidth, kVignetteHeight,
                                             Eigen::Vector4d(f, f, 0.5 * (kVignetteWidth - 1), 0.5 * (kVignetteHeight - 1)));
    options = calibrated_with_files(folder);
    options.mode = PipelineMode::Illuminated;
    options.given_calibration_holds = GivenCalibrationParts::Vignette;
    options.estimate_beam = true;
  }
  ~LampOverLensVignette() { fs::remove_all(folder); }
};

TEST(GivenCalibration, PipelineEstimatesTheBeamOverTheGivenLensVignette) {
  LampOverLensVignette setup("pipeline_beam");
  const VignetteModel& lens = setup.lens;
  const auto& camera = setup.camera;
  PipelineOptions& options = setup.options;
  {
    SlamPipeline pipeline(options, camera);
    const auto estimate = pipeline.calibration()->estimate();
    ASSERT_TRUE(estimate->beam_exponent);
    EXPECT_DOUBLE_EQ(*estimate->beam_exponent, 2.0) << "no beam configured: a 45-degree start";
    // The halo the frames are corrected with at the start: the lens vignette times cos(alpha)^2.
    const BeamHalo beam = beam_halo_for_camera(*camera, lens, 2.0);
    EXPECT_LT((estimate->vignette.v - beam.vignette(2.0)).norm(), 2e-3);
    const auto view = pipeline.photometric_view();
    EXPECT_NE(view->lamp_beam.find("cos^2.00"), std::string::npos) << view->lamp_beam;
    EXPECT_NE(view->lamp_beam.find("estimated over the given lens vignette"), std::string::npos) << view->lamp_beam;
    EXPECT_NE(view->ambiguity.find("m estimated"), std::string::npos) << view->ambiguity;
  }
  options.odometry.beam_exponent = 4.82;  // the data sheet's, as the start
  EXPECT_DOUBLE_EQ(*SlamPipeline(options, camera).calibration()->estimate()->beam_exponent, 4.82);

  // What it needs, named.
  const auto construction_error = [&](const PipelineOptions& o, std::shared_ptr<const CameraModel> cam) -> std::string {
    try {
      SlamPipeline pipeline(o, std::move(cam));
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(construction_error(options, nullptr).find("camera"), std::string::npos);
  PipelineOptions both = options;
  both.given_calibration_holds = GivenCalibrationParts::Both;
  EXPECT_NE(construction_error(both, camera).find("given_holds: vignette"), std::string::npos);
  PipelineOptions online = options;
  online.given_calibration_folder.clear();
  EXPECT_NE(construction_error(online, camera).find("calibration.given"), std::string::npos);
}

TEST(GivenCalibration, PipelineLeavesTheBeamToTheOdometry) {
  LampOverLensVignette setup("pipeline_beam_odometry");
  const VignetteModel& lens = setup.lens;
  const auto& camera = setup.camera;
  PipelineOptions& options = setup.options;
  options.odometry.beam_exponent = 4.82;
  // A uniform grey frame: corrected, its corner over its centre is 1 / V there.
  Frame frame;
  frame.image = cv::Mat(kVignetteHeight, kVignetteWidth, CV_8UC1, cv::Scalar(128));
  frame.exposure_ms = 10.0;
  const double r_corner = VignetteModel::radius(0, 0, kVignetteWidth, kVignetteHeight);
  const auto corner_over_centre = [&](const PipelineFrameResult& result) {
    return result.corrected.at<float>(0, 0) / result.corrected.at<float>(kVignetteHeight / 2, kVignetteWidth / 2);
  };
  for (const bool in_odometry : {false, true}) {
    options.beam_in_odometry = in_odometry;
    SlamPipeline pipeline(options, camera);
    ASSERT_NE(pipeline.odometry(), nullptr);
    const PipelineFrameResult result = pipeline.process(frame);
    ASSERT_FALSE(result.corrected.empty());
    const double halo_corner = VignetteModel{pipeline.calibration()->estimate()->vignette}(r_corner);
    if (in_odometry) {
      // The frames divided by the lens vignette alone; the odometry's lamp factor has the beam,
      // at the back end's current m (the start, 4.82, before any keyframe).
      EXPECT_NEAR(corner_over_centre(result), 1.0 / lens(r_corner), 0.02 / lens(r_corner));
      EXPECT_DOUBLE_EQ(pipeline.odometry()->options().beam_exponent, 4.82);
      EXPECT_NE(pipeline.calibration()->estimate()->ambiguity_detail.find("the odometry's lamp factor carries the beam"),
                std::string::npos)
          << pipeline.calibration()->estimate()->ambiguity_detail;
    } else {
      EXPECT_NEAR(corner_over_centre(result), 1.0 / halo_corner, 0.02 / halo_corner) << "the whole halo factor";
      EXPECT_LT(halo_corner, 0.8 * lens(r_corner)) << "the beam darkens the corner";
      EXPECT_DOUBLE_EQ(pipeline.odometry()->options().beam_exponent, 0.0) << "the frames no longer show the beam";
    }
  }
  // Only a held lens vignette leaves a beam to carry.
  PipelineOptions both = options;
  both.given_calibration_holds = GivenCalibrationParts::Both;
  both.estimate_beam = false;
  try {
    SlamPipeline pipeline(both, camera);
    ADD_FAILURE() << "beam_in_odometry with the whole calibration held";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("calibration.beam_in_odometry"), std::string::npos) << e.what();
  }
}

// calibration.lamp_halo: beam, the fully online lamp mode: no files, the halo factor the lamp's
// beam alone over a flat lens, m estimated and carried by the odometry.
TEST(GivenCalibration, HaloAsTheBeamAloneNeedsNoFilesAndLeavesTheBeamToTheOdometry) {
  LampOverLensVignette setup("pipeline_halo_beam");
  const auto& camera = setup.camera;
  PipelineOptions options = setup.options;
  options.given_calibration_folder.clear();
  options.estimate_beam = false;
  options.lamp_halo = LampHaloModel::Beam;
  Frame frame;
  frame.image = cv::Mat(kVignetteHeight, kVignetteWidth, CV_8UC1, cv::Scalar(128));
  frame.exposure_ms = 10.0;
  {
    SlamPipeline pipeline(options, camera);
    ASSERT_NE(pipeline.odometry(), nullptr);
    const auto estimate = pipeline.calibration()->estimate();
    ASSERT_TRUE(estimate->beam_exponent);
    EXPECT_DOUBLE_EQ(*estimate->beam_exponent, 2.0) << "no beam configured: a 45-degree start";
    // The halo the back end starts from: cos(alpha)^2 alone.
    EXPECT_LT((estimate->vignette.v - beam_halo_for_camera(*camera, VignetteModel{}, 2.0).vignette(2.0)).norm(), 2e-3);
    // The frames divided by the flat lens (not at all): a uniform frame stays uniform.
    const PipelineFrameResult result = pipeline.process(frame);
    ASSERT_FALSE(result.corrected.empty());
    EXPECT_NEAR(result.corrected.at<float>(0, 0) / result.corrected.at<float>(kVignetteHeight / 2, kVignetteWidth / 2),
                1.0, 1e-4);
    EXPECT_NE(pipeline.calibration()->estimate()->ambiguity_detail.find("the odometry's lamp factor carries the beam"),
              std::string::npos)
        << pipeline.calibration()->estimate()->ambiguity_detail;
    const auto view = pipeline.photometric_view();
    EXPECT_NE(view->lamp_beam.find("estimated over a flat lens"), std::string::npos) << view->lamp_beam;
  }
  options.odometry.beam_exponent = 4.82;  // the data sheet's, as the start
  {
    SlamPipeline pipeline(options, camera);
    EXPECT_DOUBLE_EQ(*pipeline.calibration()->estimate()->beam_exponent, 4.82);
    EXPECT_DOUBLE_EQ(pipeline.odometry()->options().beam_exponent, 4.82);
  }
  // The calibrated mode keeps the polynomial halo factor (the lamp is not modelled there).
  PipelineOptions calibrated = options;
  calibrated.mode = PipelineMode::Calibrated;
  EXPECT_FALSE(SlamPipeline(calibrated, camera).calibration()->estimate()->beam_exponent);
  // With a given calibration the beam over its lens vignette is given_holds' business.
  PipelineOptions given = options;
  given.given_calibration_folder = setup.folder;
  try {
    SlamPipeline pipeline(given, camera);
    ADD_FAILURE() << "lamp_halo: beam with a given calibration";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("calibration.lamp_halo"), std::string::npos) << e.what();
  }
}

// The lamp-lit response is weakly determined online (README "Illuminator correction", session
// 41), so the fully online lamp mode can hold one from a sweep: given_holds: response with
// lamp_halo: beam holds pcalib.txt, the lens flat, the beam's m estimated and left to the odometry.
TEST(GivenCalibration, HaloAsTheBeamOverAGivenResponse) {
  const ResponseModel response = ResponseModel::from_preset(ResponsePreset::Filmic);
  LampOverLensVignette setup("pipeline_halo_beam_response");
  write_pcalib(setup.folder / "pcalib.txt", response.inverse_table(256));
  const auto& camera = setup.camera;
  PipelineOptions options = setup.options;
  options.given_calibration_holds = GivenCalibrationParts::Response;
  options.estimate_beam = false;
  options.lamp_halo = LampHaloModel::Beam;
  options.odometry.beam_exponent = 4.82;
  SlamPipeline pipeline(options, camera);
  auto estimate = pipeline.calibration()->estimate();
  ASSERT_TRUE(estimate->beam_exponent);
  EXPECT_DOUBLE_EQ(*estimate->beam_exponent, 4.82);
  EXPECT_LT((estimate->vignette.v - beam_halo_for_camera(*camera, VignetteModel{}, 4.82).vignette(4.82)).norm(), 2e-3)
      << "the halo factor starts as the beam over a flat lens, not the folder's vignette.png";
  EXPECT_LT((estimate->response.coefficients() - response.coefficients()).norm(), 1e-3);
  EXPECT_DOUBLE_EQ(pipeline.odometry()->options().beam_exponent, 4.82) << "the odometry's lamp factor carries the beam";
  const std::string& given = pipeline.options().calibration.given_part;
  EXPECT_NE(given.find("response given"), std::string::npos) << given;
  EXPECT_NE(given.find("a flat lens"), std::string::npos) << given;
  // Frames are G(I) of the held response over the flat lens; the response never re-estimated.
  feed_noise_frames(pipeline, 8, [&](int, const Frame& frame, const PipelineFrameResult& result) {
    const double grey = frame.image.at<std::uint8_t>(0, 0);
    EXPECT_NEAR(result.corrected.at<float>(0, 0), 255.0 * response.inverse(grey / 255.0), 0.02 * grey + 0.5);
  });
  estimate = pipeline.calibration()->estimate();
  EXPECT_LT((estimate->response.coefficients() - response.coefficients()).norm(), 1e-3);
}

TEST(GivenCalibration, PipelineHoldsTheGivenModel) {
  const ResponseModel response = ResponseModel::from_preset(ResponsePreset::Filmic);
  const VignetteModel vignette{Eigen::Vector3d(-0.25, 0.0, 0.0)};
  const fs::path folder = write_dso_files("pipeline", response, vignette);
  PipelineOptions options = calibrated_with_files(folder);
  // No camera: the odometry stays off (this test is about the held model, and the odometry on
  // noise frames cost 20 s under the sanitizers).
  SlamPipeline pipeline(options, nullptr);
  ASSERT_NE(pipeline.calibration(), nullptr);
  feed_noise_frames(pipeline, 12, [&](int, const Frame& frame, const PipelineFrameResult& result) {
    // G(I)/V of the given model at the centre.
    const double grey_centre = frame.image.at<std::uint8_t>(kVignetteHeight / 2, kVignetteWidth / 2);
    const double irradiance_centre = 255.0 * response.inverse(grey_centre / 255.0) /
                                     vignette(VignetteModel::radius(kVignetteWidth / 2, kVignetteHeight / 2, kVignetteWidth, kVignetteHeight));
    EXPECT_NEAR(result.corrected.at<float>(kVignetteHeight / 2, kVignetteWidth / 2), irradiance_centre, 0.05 * irradiance_centre + 0.5);
  });
  const auto estimate = pipeline.calibration()->estimate();
  EXPECT_EQ(estimate->model_version, 0) << "held, never re-estimated";
  EXPECT_EQ(estimate->ambiguity, AmbiguityResolution::Given);
  EXPECT_LT((estimate->response.coefficients() - response.coefficients()).norm(), 1e-3);
  EXPECT_LT((estimate->vignette.v - vignette.v).norm(), 2e-3);
  const auto view = pipeline.photometric_view();
  EXPECT_NE(view->ambiguity.find("given calibration"), std::string::npos) << view->ambiguity;
  EXPECT_NE(view->ambiguity.find("pcalib.txt"), std::string::npos) << view->ambiguity;
  fs::remove_all(folder);
}

}  // namespace
}  // namespace nirslam
