// Response calibration from a static exposure sweep (issue 6): synthetic sweeps with a known
// response, the real Canon S45 stack with its recorded shutter times, and degenerate input.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/image/image_files.hpp"
#include "nirslam/photometric/exposure_sweep_calibration.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

// A static scene of 8x8-pixel patches with log-uniform radiance in [0.02, 1], seen with the
// given exposures through `response`, Gaussian noise of `noise_grey`, quantised to 8 bit.
std::vector<cv::Mat> render_sweep(const ResponseModel& response, const std::vector<double>& exposures,
                                  double noise_grey, unsigned seed) {
  constexpr int kWidth = 256, kHeight = 192, kPatch = 8;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> log_l(std::log(0.02), std::log(1.0));
  std::normal_distribution<double> noise(0.0, noise_grey);
  cv::Mat radiance(kHeight / kPatch, kWidth / kPatch, CV_64FC1);
  for (int r = 0; r < radiance.rows; ++r)
    for (int c = 0; c < radiance.cols; ++c) radiance.at<double>(r, c) = std::exp(log_l(rng));
  std::vector<cv::Mat> images;
  for (double e : exposures) {
    cv::Mat image(kHeight, kWidth, CV_8UC1);
    for (int r = 0; r < kHeight; ++r)
      for (int c = 0; c < kWidth; ++c) {
        const double grey = 255.0 * response(e * radiance.at<double>(r / kPatch, c / kPatch)) + noise(rng);
        image.at<unsigned char>(r, c) = static_cast<unsigned char>(std::clamp(std::lround(grey), 0L, 255L));
      }
    images.push_back(image);
  }
  return images;
}

const std::vector<double> kExposures = {1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125};

TEST(ExposureSweep, PredictionMatchesResponseModelAndJacobianIsNumeric) {
  const Eigen::Vector4d c(0.3, -0.2, 0.1, 0.05);
  const ResponseModel f(c);
  for (double X : {0.001, 0.05, 0.3, 0.7, 0.99}) {
    Eigen::Matrix<double, 5, 1> jac;
    const double value = sweep_prediction(c, std::log(X), &jac);
    EXPECT_NEAR(value, f(X), 1e-12);
    const double h = 1e-6;
    for (int k = 0; k < 4; ++k) {
      Eigen::Vector4d cp = c, cm = c;
      cp[k] += h;
      cm[k] -= h;
      EXPECT_NEAR(jac[k], (sweep_prediction(cp, std::log(X)) - sweep_prediction(cm, std::log(X))) / (2 * h), 1e-7);
    }
    EXPECT_NEAR(jac[4], (sweep_prediction(c, std::log(X) + h) - sweep_prediction(c, std::log(X) - h)) / (2 * h), 1e-7);
  }
}

class ExposureSweepPresets : public ::testing::TestWithParam<ResponsePreset> {};

TEST_P(ExposureSweepPresets, KnownExposuresRecoverResponseWithinTwoGreyLevels) {
  const ResponseModel truth = ResponseModel::from_preset(GetParam());
  const auto images = render_sweep(truth, kExposures, 0.7, 11);
  const ExposureSweepResult result = calibrate_exposure_sweep(images, kExposures);
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_EQ(result.resolution, SweepAmbiguityResolution::KnownExposureTimes);
  EXPECT_TRUE(result.monotonic);
  EXPECT_LT(result.residual_rms_grey, 1.5);
  EXPECT_GT(result.point_count, 500);
  // Without samples at saturation the irradiance unit is not pinned (f(X) and f(kX) fit alike
  // within the data, see the header): compare f_est(k X) with f_true(X) for the best k, over the
  // data's range X = e L in [0.02 * 0.03125, 1].
  double worst = 1e9, best_k = 0.0;
  for (double k = 0.5; k <= 2.0; k *= 1.002) {
    double err = 0.0;
    for (double X = 0.0006; X <= 1.0 / k && X <= 1.0; X *= 1.05)
      err = std::max(err, 255.0 * std::abs(result.response(k * X) - truth(X)));
    if (err < worst) {
      worst = err;
      best_k = k;
    }
  }
  EXPECT_LT(worst, 2.0) << to_string(GetParam()) << " best scale " << best_k;
  std::printf("%s: worst %.2f grey at scale %.3f, rms %.2f\n", std::string(to_string(GetParam())).c_str(), worst,
              best_k, result.residual_rms_grey);
  for (std::size_t j = 0; j < kExposures.size(); ++j) EXPECT_DOUBLE_EQ(result.images[j].ratio, kExposures[j]);
}

TEST_P(ExposureSweepPresets, UnknownExposuresWithFixedResponseRecoverRatiosWithinTwoPercent) {
  const ResponseModel truth = ResponseModel::from_preset(GetParam());
  const auto images = render_sweep(truth, kExposures, 0.7, 12);
  ExposureSweepOptions options;
  options.prior = truth;
  options.fix_response = true;
  const ExposureSweepResult result = calibrate_exposure_sweep(images, std::nullopt, options);
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_EQ(result.resolution, SweepAmbiguityResolution::FixedPriorResponse);
  EXPECT_EQ(result.reference_image, 0);
  EXPECT_EQ(result.response.coefficients(), truth.coefficients());
  for (std::size_t j = 0; j < kExposures.size(); ++j) {
    ASSERT_TRUE(result.images[j].used);
    EXPECT_NEAR(result.images[j].ratio / kExposures[j], 1.0, 0.02) << to_string(GetParam()) << " image " << j;
  }
}

// Response and exposures both unknown: the fit explains the data and stays monotonic, but the
// ratios are only as good as the gamma normalisation (see the header; measured: Gamma and Filmic
// within 2.5%, Log off by a power of about 1.7), so only their order and the label are checked.
TEST_P(ExposureSweepPresets, UnknownExposuresJointFitIsMonotonicAndSaysWhichNormalisation) {
  const ResponseModel truth = ResponseModel::from_preset(GetParam());
  const auto images = render_sweep(truth, kExposures, 0.7, 14);
  const ExposureSweepResult result = calibrate_exposure_sweep(images, std::nullopt);
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_EQ(result.resolution, SweepAmbiguityResolution::ReferenceImageNormalisation);
  EXPECT_NE(to_string(result.resolution).find("e_ref = 1"), std::string::npos);
  EXPECT_TRUE(result.monotonic);
  EXPECT_LT(result.residual_rms_grey, 1.5);
  EXPECT_DOUBLE_EQ(result.images[0].ratio, 1.0);
  for (std::size_t j = 1; j < kExposures.size(); ++j) EXPECT_LT(result.images[j].ratio, result.images[j - 1].ratio);
}

INSTANTIATE_TEST_SUITE_P(Presets, ExposureSweepPresets,
                         ::testing::Values(ResponsePreset::Gamma, ResponsePreset::Log, ResponsePreset::Filmic));

// The Canon S45 stack (../shared/data/exposure_stack_canon_s45): 13 colour JPEGs, tripod, shutter
// times 13 s .. 1/1000 s in shutter.txt. The green channel is used, not the grey conversion: a
// pixel whose red or blue channel saturates has an unclipped-looking grey value that no
// response explains. JPEG's tone curve rolls off softly into saturation, so samples above 245
// count as clipped. Images are halved for speed.
struct CanonStack {
  std::vector<NamedExposureTime> times;
  std::vector<cv::Mat> green;
};

// README Next 5 of session 45: a camera whose reported exposure is not the frame's own. Each
// image's brightness is checked against its given exposure; with the true times every image
// agrees, and a camera that reports its previous frame's exposure (a setting read back late)
// is caught: the sweep's first image is the odd one out against the five after it, which agree
// among themselves.
TEST(ExposureSweep, ImagesWhoseBrightnessDisagreesWithTheirReportedExposureAreNamed) {
  const ResponseModel truth = ResponseModel::from_preset(ResponsePreset::Gamma);
  const auto images = render_sweep(truth, kExposures, 0.7, 5);
  const ExposureSweepResult right = calibrate_exposure_sweep(images, kExposures);
  ASSERT_TRUE(right.ok) << right.reason;
  EXPECT_TRUE(right.reported_exposure_check.empty()) << right.reported_exposure_check;
  double worst = 0.0;
  for (const ExposureSweepImage& info : right.images) worst = std::max(worst, std::abs(std::log(info.brightness_exposure_factor)));
  EXPECT_LT(worst, std::log(1.02)) << "true exposures: every image within 2 %";

  // Reported one frame late: 1, 1, 0.5, 0.25, ... for the true 1, 0.5, 0.25, 0.125, ...
  std::vector<double> late = kExposures;
  for (std::size_t j = late.size() - 1; j > 0; --j) late[j] = late[j - 1];
  const ExposureSweepResult lagging = calibrate_exposure_sweep(images, late);
  ASSERT_TRUE(lagging.ok) << lagging.reason;
  // Only the odd image is named, in front of the explanation: "image 0 (1.80x): ...".
  const auto named_alone = [](const std::string& check, const std::string& image) {
    const std::string named = check.substr(0, check.find(':'));
    return named.rfind(image + " (", 0) == 0 && named.find(',') == std::string::npos;
  };
  EXPECT_TRUE(named_alone(lagging.reported_exposure_check, "image 0")) << lagging.reported_exposure_check;
  // Against the five that agree (each reported 2x its truth, so the radiances come out halved), the
  // first is about twice as bright as its given exposure predicts: measured 1.80, the joint fit's
  // response absorbing part of it, and the five within 6 % of 1 (0.944-1.041).
  EXPECT_GT(lagging.images[0].brightness_exposure_factor, 1.5);
  EXPECT_LT(lagging.images[0].brightness_exposure_factor, 2.2);
  for (std::size_t j = 1; j < late.size(); ++j)
    EXPECT_NEAR(lagging.images[j].brightness_exposure_factor, 1.0, 0.08) << "image " << j;

  // One image's exposure wrong alone (the fourth, given as twice its own).
  std::vector<double> one_wrong = kExposures;
  one_wrong[3] *= 2.0;
  const ExposureSweepResult single = calibrate_exposure_sweep(images, one_wrong);
  ASSERT_TRUE(single.ok) << single.reason;
  EXPECT_TRUE(named_alone(single.reported_exposure_check, "image 3")) << single.reported_exposure_check;
  EXPECT_NEAR(single.images[3].brightness_exposure_factor, 0.5, 0.1);  // measured 0.518, the others 1.003-1.050
  std::printf("brightness factors, true / late / one wrong:");
  for (std::size_t j = 0; j < late.size(); ++j)
    std::printf(" %.3f/%.3f/%.3f", right.images[j].brightness_exposure_factor, lagging.images[j].brightness_exposure_factor,
                single.images[j].brightness_exposure_factor);
  std::printf("\n");
}

CanonStack load_canon_stack() {
  CanonStack stack;
  const fs::path dir = fs::path(NIRSLAM_SHARED_DATA_DIR) / "exposure_stack_canon_s45";
  if (!fs::exists(dir / "shutter.txt")) return stack;
  stack.times = read_exposure_times(dir / "shutter.txt");
  for (const auto& t : stack.times) {
    cv::Mat colour;
    try {
      colour = nirslam::read_image(dir / (t.name + ".jpg"), nirslam::ImageReadMode::Bgr);
    } catch (const std::runtime_error&) {
      return {};
    }
    cv::Mat green, half;
    cv::extractChannel(colour, green, 1);
    cv::resize(green, half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
    stack.green.push_back(half);
  }
  return stack;
}

ExposureSweepOptions canon_options() {
  ExposureSweepOptions options;
  options.max_valid_grey = 245;
  return options;
}

TEST(ExposureSweep, RealCanonStackKnownTimesGiveMonotonicResponse) {
  const CanonStack stack = load_canon_stack();
  if (stack.green.empty()) GTEST_SKIP() << "no exposure_stack_canon_s45";
  ASSERT_EQ(stack.times.size(), 13u);
  std::vector<double> shutter;
  for (const auto& t : stack.times) shutter.push_back(t.seconds);
  const ExposureSweepResult result = calibrate_exposure_sweep(stack.green, shutter, canon_options());
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_TRUE(result.monotonic);
  EXPECT_TRUE(result.response.is_monotonic());
  EXPECT_LT(result.residual_rms_grey, 2.5);
  EXPECT_GT(result.point_count, 2000);
  const auto& c = result.response.coefficients();
  std::printf("known times: reference %s, points %d, observations %d, rms %.3f grey, iterations %d, c = %.4f %.4f %.4f %.4f\n",
              stack.times[static_cast<std::size_t>(result.reference_image)].name.c_str(), result.point_count,
              result.observation_count, result.residual_rms_grey, result.iterations, c[0], c[1], c[2], c[3]);
  for (std::size_t j = 0; j < stack.green.size(); ++j)
    std::printf("  %s: used %d, unclipped %d, rms %.2f, brightness %.3fx %s\n", stack.times[j].name.c_str(),
                result.images[j].used ? 1 : 0, result.images[j].unclipped_samples, result.images[j].residual_rms_grey,
                result.images[j].brightness_exposure_factor, result.images[j].note.c_str());
  // The recorded shutter times are the camera's own: no image is named as disagreeing with its
  // brightness beyond the stack's scatter.
  EXPECT_TRUE(result.reported_exposure_check.empty()) << result.reported_exposure_check;
  // The darkest frame (1/1000 s) is nearly black at this scale: excluded, and said so.
  EXPECT_FALSE(result.images[12].used);
  EXPECT_NE(result.images[12].note.find("mostly black"), std::string::npos);
}

TEST(ExposureSweep, RealCanonStackEstimatedRatiosMatchShutterTimesWithinFivePercent) {
  const CanonStack stack = load_canon_stack();
  if (stack.green.empty()) GTEST_SKIP() << "no exposure_stack_canon_s45";
  std::vector<double> shutter;
  for (const auto& t : stack.times) shutter.push_back(t.seconds);
  // Step 1: the response from the sweep with the recorded times.
  // Measured (green channel, half size): img02..img08 within 5% (largest -4.6%, img08); the four
  // short exposures img09..img12 (1/60, 1/80, 1/320, 1/400 s, 175..667 of 3000 samples
  // unclipped, all in the toe of the curve) are off by +12%, +10%, -13%, -16%: consistent over
  // clipping thresholds and Huber widths, and the known-times fit also leaves its largest
  // residuals there, so either the nominal short shutter times or the 4-coefficient toe is off. Step 2: the exposures estimated
  // as unknowns with that response held fixed (the per-frame exposure estimate of the pipeline).
  const ExposureSweepResult calibrated = calibrate_exposure_sweep(stack.green, shutter, canon_options());
  ASSERT_TRUE(calibrated.ok) << calibrated.reason;
  ExposureSweepOptions options = canon_options();
  options.prior = calibrated.response;
  options.fix_response = true;
  const ExposureSweepResult result = calibrate_exposure_sweep(stack.green, std::nullopt, options);
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_EQ(result.resolution, SweepAmbiguityResolution::FixedPriorResponse);
  const auto ref = static_cast<std::size_t>(result.reference_image);
  int compared = 0;
  for (std::size_t j = 0; j < stack.green.size(); ++j) {
    const auto& info = result.images[j];
    const double expected = shutter[j] / shutter[ref];
    std::printf("  %s: shutter %.5g s, used %d, ratio %.5g, shutter ratio %.5g, error %+.2f%%, rms %.2f %s\n",
                stack.times[j].name.c_str(), shutter[j], info.used ? 1 : 0, info.ratio, expected,
                info.used ? 100.0 * (info.ratio / expected - 1.0) : 0.0, info.residual_rms_grey, info.note.c_str());
    if (!info.used) continue;
    ++compared;
    // 13 s .. 1/4 s: within 5%. 1/60 .. 1/400 s: 8-17% off (see the report in the header of
    // this test), held to 20% so that a regression shows.
    EXPECT_NEAR(info.ratio / expected, 1.0, j < 8 ? 0.05 : 0.20) << stack.times[j].name;
  }
  std::printf("estimated exposures: reference %s, rms %.3f grey\n", stack.times[ref].name.c_str(), result.residual_rms_grey);
  EXPECT_GE(compared, 12);
}

void expect_degenerate(const ExposureSweepResult& result, const std::string& reason_part) {
  EXPECT_FALSE(result.ok);
  EXPECT_NE(result.reason.find(reason_part), std::string::npos) << result.reason;
  EXPECT_TRUE(result.response.coefficients().allFinite());
  EXPECT_TRUE(std::isfinite(result.residual_rms_grey));
  for (const auto& image : result.images) {
    EXPECT_TRUE(std::isfinite(image.exposure));
    EXPECT_TRUE(std::isfinite(image.ratio));
  }
}

TEST(ExposureSweep, DegenerateInputKeepsPriorAndSaysWhy) {
  ExposureSweepOptions options;
  options.prior = ResponseModel::from_preset(ResponsePreset::Log);
  const std::vector<cv::Mat> black(4, cv::Mat(64, 64, CV_8UC1, cv::Scalar(0)));
  const std::vector<cv::Mat> white(4, cv::Mat(64, 64, CV_8UC1, cv::Scalar(255)));
  for (const auto& times : {std::optional<std::vector<double>>{}, std::optional<std::vector<double>>{{1.0, 2.0, 4.0, 8.0}}}) {
    const auto r_black = calibrate_exposure_sweep(black, times, options);
    expect_degenerate(r_black, "black or saturated");
    EXPECT_EQ(r_black.response.coefficients(), options.prior.coefficients());
    EXPECT_NE(r_black.images[0].note.find("mostly black"), std::string::npos);
    const auto r_white = calibrate_exposure_sweep(white, times, options);
    expect_degenerate(r_white, "black or saturated");
    EXPECT_NE(r_white.images[0].note.find("mostly saturated"), std::string::npos);
  }
  const auto sweep = render_sweep(ResponseModel::from_preset(ResponsePreset::Gamma), kExposures, 0.7, 13);
  expect_degenerate(calibrate_exposure_sweep({sweep[0]}, std::nullopt, options), "fewer than 2 images");
  expect_degenerate(calibrate_exposure_sweep({}, std::nullopt, options), "fewer than 2 images");
  const std::vector<cv::Mat> same = {sweep[1], sweep[1].clone(), sweep[1].clone()};
  expect_degenerate(calibrate_exposure_sweep(same, std::nullopt, options), "no exposure variation");
  expect_degenerate(calibrate_exposure_sweep(same, std::vector<double>{0.5, 0.5, 0.5}, options), "no exposure variation");
  expect_degenerate(calibrate_exposure_sweep({sweep[0], sweep[1]}, std::vector<double>{1.0}, options), "exposure times");
  expect_degenerate(calibrate_exposure_sweep({sweep[0], sweep[1]}, std::vector<double>{1.0, std::nan("")}, options),
                    "not positive");
  // A few unclipped pixels only: too few tracks.
  std::vector<cv::Mat> sparse = {cv::Mat(64, 64, CV_8UC1, cv::Scalar(0)), cv::Mat(64, 64, CV_8UC1, cv::Scalar(0))};
  for (int k = 0; k < 2; ++k) {
    sparse[static_cast<std::size_t>(k)](cv::Rect(20, 20, 6, 6)).setTo(cv::Scalar(60 + 60 * k));
  }
  ExposureSweepOptions sparse_options = options;
  sparse_options.min_unclipped_fraction = 0.0;
  expect_degenerate(calibrate_exposure_sweep(sparse, std::nullopt, sparse_options), "too few unclipped tracks");
  cv::Mat colour(64, 64, CV_8UC3, cv::Scalar(1, 2, 3));
  expect_degenerate(calibrate_exposure_sweep({colour, colour}, std::nullopt, options), "8-bit grey");
}

// A static scene of 8x8-pixel patches under the rig's lamp at `powers` (relative to the strongest)
// and, on every other patch, ambient light that does not follow the lamp: X = P R + A with the
// lamp radiance R log-uniform in [0.03, 1] and A / R log-uniform in [0.02, 1]. The noise as in
// render_sweep.
std::vector<cv::Mat> render_power_sweep(const ResponseModel& response, const std::vector<double>& powers,
                                        double noise_grey, unsigned seed, double exposure = 1.0) {
  constexpr int kWidth = 256, kHeight = 192, kPatch = 8;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> log_r(std::log(0.03), std::log(1.0));
  std::uniform_real_distribution<double> log_share(std::log(0.02), std::log(1.0));
  std::normal_distribution<double> noise(0.0, noise_grey);
  cv::Mat lamp(kHeight / kPatch, kWidth / kPatch, CV_64FC1), ambient(lamp.size(), CV_64FC1);
  for (int r = 0; r < lamp.rows; ++r)
    for (int c = 0; c < lamp.cols; ++c) {
      lamp.at<double>(r, c) = std::exp(log_r(rng));
      ambient.at<double>(r, c) = (r + c) % 2 == 0 ? lamp.at<double>(r, c) * std::exp(log_share(rng)) : 0.0;
    }
  std::vector<cv::Mat> images;
  for (double power : powers) {
    cv::Mat image(kHeight, kWidth, CV_8UC1);
    for (int r = 0; r < kHeight; ++r)
      for (int c = 0; c < kWidth; ++c) {
        const double X =
            exposure * (power * lamp.at<double>(r / kPatch, c / kPatch) + ambient.at<double>(r / kPatch, c / kPatch));
        const double grey = 255.0 * response(X) + noise(rng);
        image.at<unsigned char>(r, c) = static_cast<unsigned char>(std::clamp(std::lround(grey), 0L, 255L));
      }
    images.push_back(image);
  }
  return images;
}

// The worst grey-level error of `estimate` against `truth` over X in [lowest, 1] at the best
// common irradiance scale k (the data fix f only up to X -> kX without saturated samples).
double worst_error_at_best_scale(const ResponseModel& estimate, const ResponseModel& truth, double lowest) {
  double worst = 1e9;
  for (double k = 0.5; k <= 2.0; k *= 1.002) {
    double err = 0.0;
    for (double X = lowest; X <= 1.0 / k && X <= 1.0; X *= 1.05)
      err = std::max(err, 255.0 * std::abs(estimate(k * X) - truth(X)));
    worst = std::min(worst, err);
  }
  return worst;
}

TEST(PowerSweep, LogIrradianceDerivativeByTheAmbientShareIsNumeric) {
  for (const double q : {0.0, 0.5, 3.0})
    for (const double b : {0.01, 0.4, 2.0}) {
      double d_ambient = 0.0;
      const double value = power_sweep_log_irradiance(-1.2, b, q, 1.7, &d_ambient);
      EXPECT_NEAR(value, -1.2 + std::log(q + 1.7 * b), 1e-12);
      const double h = 1e-6;
      const double numeric =
          (power_sweep_log_irradiance(-1.2, b + h, q, 1.7) - power_sweep_log_irradiance(-1.2, b - h, q, 1.7)) / (2 * h);
      EXPECT_NEAR(d_ambient, numeric, 1e-6 * std::max(1.0, std::abs(numeric))) << q << " " << b;
    }
}

// Issue 6's power-sweep route to the response, outdoors or beside other lights: with the ambient
// term the response is as good as with the lamp alone; without it the ambient light bends it.
TEST(PowerSweep, AmbientTermRecoversTheResponseUnderAmbientLight) {
  const std::vector<double> powers_w = {0.0, 5.0, 10.0, 20.0, 40.0, 65.0, 100.0, 150.0};
  std::vector<double> relative;
  std::vector<PowerSweepFrame> frames;
  for (double p : powers_w) {
    relative.push_back(p / 150.0);
    frames.push_back({p, 4.0});
  }
  const ResponseModel truth = ResponseModel::from_preset(ResponsePreset::Gamma);
  const auto images = render_power_sweep(truth, relative, 0.7, 17);
  const ExposureSweepResult with = calibrate_power_sweep(images, frames, true);
  ASSERT_TRUE(with.ok) << with.reason;
  EXPECT_EQ(with.resolution, SweepAmbiguityResolution::IlluminatorPowerSweep);
  EXPECT_TRUE(with.ambient_modelled);
  EXPECT_TRUE(with.images[0].used) << "the lamp-off image shows the ambient light";
  EXPECT_EQ(with.reference_image, 1);
  EXPECT_EQ(with.weakest_image, 1);
  const ExposureSweepResult without = calibrate_power_sweep(images, frames, false);
  ASSERT_TRUE(without.ok) << without.reason;
  EXPECT_FALSE(without.ambient_modelled);
  EXPECT_FALSE(without.images[0].used);
  EXPECT_NE(without.images[0].note.find("0 W"), std::string::npos);
  const double lowest = 0.03 * 5.0 / 150.0;
  const double error_with = worst_error_at_best_scale(with.response, truth, lowest);
  const double error_without = worst_error_at_best_scale(without.response, truth, lowest);
  std::printf("power sweep under ambient light: worst %.2f grey levels with the ambient term (residual %.2f, ambient "
              "share %.2f at 5 W), %.2f without (residual %.2f)\n",
              error_with, with.residual_rms_grey, with.ambient_share_at_weakest, error_without,
              without.residual_rms_grey);
  EXPECT_LT(error_with, 1.5);
  EXPECT_LT(with.residual_rms_grey, 1.0);
  EXPECT_GT(error_without, 3.0 * error_with);
  // Half the patches have no ambient light: the median share at 5 W lies between theirs (0)
  // and the lit ones' (A / R in [0.02, 1], at 5 W x 30 that).
  EXPECT_GT(with.ambient_share_at_weakest, 0.0);
  EXPECT_LT(with.ambient_share_at_weakest, 30.0);
  // Without ambient light the term finds none and costs the response nothing.
  const auto lamp_only = render_sweep(truth, {relative.begin() + 1, relative.end()}, 0.7, 19);
  const std::vector<PowerSweepFrame> lit_frames(frames.begin() + 1, frames.end());
  const ExposureSweepResult alone = calibrate_power_sweep(lamp_only, lit_frames, true);
  ASSERT_TRUE(alone.ok) << alone.reason;
  const double error_alone = worst_error_at_best_scale(alone.response, truth, 0.02 * 5.0 / 150.0);
  std::printf("power sweep, lamp the only light: worst %.2f grey levels, ambient share %.4f\n", error_alone,
              alone.ambient_share_at_weakest);
  EXPECT_LT(error_alone, 1.5);
  EXPECT_LT(std::abs(alone.ambient_share_at_weakest), 0.05);
}

// A sweep whose images stop short of the top fits the response exactly up to where they stop,
// but its scale (f(1) = 1) rests on the basis's continuation above: it says so and by how much to
// lengthen the exposure; the sweep taken again so reaches the top and the response with it.
TEST(PowerSweep, ImagesThatStopShortOfTheTopAreSaidToBeExtrapolated) {
  const std::vector<double> powers_w = {5.0, 10.0, 20.0, 40.0, 65.0, 100.0, 150.0};
  std::vector<double> relative;
  for (double p : powers_w) relative.push_back(0.5 * p / 150.0);
  const ResponseModel truth = ResponseModel::from_preset(ResponsePreset::Gamma);
  const std::vector<double> truth_table = truth.inverse_table();
  const auto mean_error = [&](const ResponseModel& estimate) {
    const std::vector<double> table = estimate.inverse_table();
    double sum = 0.0;
    for (std::size_t k = 0; k < table.size(); ++k) sum += std::abs(table[k] - truth_table[k]);
    return sum / static_cast<double>(table.size());
  };
  double error[2] = {0.0, 0.0};
  double advised = 1.0;
  for (const int bright : {0, 1}) {
    // The same scene at 1/8 of the exposure, then at the exposure the first sweep advises.
    const double exposure = bright ? 0.125 * advised : 0.125;
    std::vector<PowerSweepFrame> frames;
    for (double p : powers_w) frames.push_back({p, 8.0 * exposure});
    const auto images = render_power_sweep(truth, relative, 0.7, 29, exposure);
    const ExposureSweepResult fit = calibrate_power_sweep(images, frames, true);
    ASSERT_TRUE(fit.ok) << fit.reason;
    error[bright] = mean_error(fit.response);
    std::printf("power sweep at exposure %.3f: samples reach grey %.0f, response %.2f grey levels mean error\n",
                exposure, fit.highest_grey, error[bright]);
    if (bright) {
      EXPECT_GT(fit.highest_grey, kSweepAdvisedHighestGrey) << "the advised exposure reaches the top";
      EXPECT_LT(fit.highest_grey, 240.0) << "without clipping much";
      EXPECT_TRUE(sweep_range_advice(fit).empty()) << sweep_range_advice(fit);
    } else {
      EXPECT_LT(fit.highest_grey, kSweepAdvisedHighestGrey);
      const std::string advice = sweep_range_advice(fit);
      EXPECT_NE(advice.find(fmt::format("grey {:.0f} at most", fit.highest_grey)), std::string::npos) << advice;
      advised = sweep_exposure_factor(fit);
      EXPECT_NE(advice.find(fmt::format("about {:.1f}x the exposure", advised)), std::string::npos) << advice;
      EXPECT_GT(advised, 2.0);
    }
  }
  EXPECT_LT(error[1], 1.0);
  EXPECT_GT(error[0], 2.0);  // measured 5.2 (0.05 with the top reached)
}

TEST(PowerSweep, BadPowersOrExposuresKeepThePriorAndSayWhy) {
  const auto images = render_sweep(ResponseModel::from_preset(ResponsePreset::Gamma), {1.0, 0.5, 0.25}, 0.7, 23);
  const auto short_list = calibrate_power_sweep(images, {{10.0, 4.0}, {5.0, 4.0}}, true);
  EXPECT_FALSE(short_list.ok);
  EXPECT_NE(short_list.reason.find("2 powers and exposures for 3 images"), std::string::npos) << short_list.reason;
  const auto negative = calibrate_power_sweep(images, {{10.0, 4.0}, {-5.0, 4.0}, {2.5, 4.0}}, true);
  EXPECT_FALSE(negative.ok);
  EXPECT_NE(negative.reason.find("image 1"), std::string::npos) << negative.reason;
  const auto all_off = calibrate_power_sweep(images, {{0.0, 4.0}, {0.0, 4.0}, {0.0, 2.0}}, true);
  EXPECT_FALSE(all_off.ok);
  EXPECT_NE(all_off.reason.find("lamp-off"), std::string::npos) << all_off.reason;
}

TEST(ExposureTimes, ReadsNamesAndFractionsAndNamesTheBadLine) {
  const fs::path dir = fs::temp_directory_path() / ("nirslam_sweep_times_" + std::to_string(std::random_device{}()));
  fs::create_directories(dir);
  {
    std::ofstream out(dir / "good.txt");
    out << "A picture set\nhttp://example.org/x\n\n# comment\nimg01: 13\nimg02:   1/250\n";
  }
  const auto times = read_exposure_times(dir / "good.txt");
  ASSERT_EQ(times.size(), 2u);
  EXPECT_EQ(times[0].name, "img01");
  EXPECT_DOUBLE_EQ(times[0].seconds, 13.0);
  EXPECT_DOUBLE_EQ(times[1].seconds, 1.0 / 250.0);
  {
    std::ofstream out(dir / "bad.txt");
    out << "img01: 13\nimg02: 1/0\n";
  }
  try {
    read_exposure_times(dir / "bad.txt");
    FAIL() << "expected InputError";
  } catch (const InputError& error) {
    EXPECT_EQ(error.line(), 2);
    EXPECT_EQ(error.file(), dir / "bad.txt");
  }
  {
    std::ofstream out(dir / "none.txt");
    out << "just text\n";
  }
  EXPECT_THROW(read_exposure_times(dir / "none.txt"), InputError);
  EXPECT_THROW(read_exposure_times(dir / "missing.txt"), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace nirslam
