#pragma once

// Response calibration from a static exposure sweep (issue 6): N grey images of a static scene
// taken from a tripod with different exposures. Pixel i in image j obeys (DESIGN.md, "The
// photometric model", with V folded into the per-point radiance because the camera does not move)
//
//   I_ij / 255 = f(e_j * L_i)
//
// with f the project's ResponseModel (four coefficients c1..c4). Unknowns: c, log L_i per sampled
// point, and (when the exposure times are not given) log e_j.
//
// The residual lives in the grey domain, r_ij = f(exp(log_radiance_i + log_exposure_j)) - I_ij/255:
// the noise of an 8-bit image (read noise, quantisation, JPEG) is roughly constant in grey levels,
// while in the log-irradiance domain it would blow up near black, where the inverse response is
// steep. A Huber loss (width in grey levels) takes care of JPEG ringing and slight misalignment.
// Solver: hand-written Levenberg-Marquardt with the Schur complement over the per-point log
// radiances (each point is a 1x1 block), analytic Jacobians (see sweep_prediction).
//
// Monotonicity: the fit carries a penalty on df/du < 0.01 (u = sqrt(X)) on a grid of u in [0, 1];
// the result reports ResponseModel::is_monotonic() of the estimate and rejects (keeps the prior)
// a non-monotonic one.
//
// Ambiguity (DESIGN.md): f(X^g), e^g, L^g fit (almost) equally well, and so do e*k, L/k.
//  - Known exposure times (SweepAmbiguityResolution::KnownExposureTimes) resolve the gamma:
//    log e_j is fixed to log(t_j / t_ref); the irradiance unit is absorbed by the radiances and
//    pinned by f(1) = 1 when samples reach close to saturation (else f is known up to X -> kX,
//    which a correction G(I) / e does not care about).
//  - Unknown exposure times, response estimated too (ReferenceImageNormalisation): the scale is
//    fixed by e_ref = 1 for the reference image (the first used image); the gamma is pinned only
//    by the response basis itself (f(0) = 0, f(1) = 1, sqrt-like near black) and the weak prior on
//    c. That is NOT reliable: on synthetic sweeps Gamma and Filmic come out within 2.5%, Log off
//    by a power of ~1.7; on the real Canon S45 stack the ratios are off by a power of ~3 while the
//    residual is lower than with the true times. Use it only for relative, self-consistent
//    corrections, never for exposure ratios.
//  - Unknown exposure times, response held at options.prior (FixedPriorResponse, fix_response):
//    e_ref = 1 and f = prior; this is the reliable way to estimate exposures, with a response
//    calibrated before from known times (the test on the real stack does exactly this).
// Degenerate input (fewer than two usable images, black or saturated images, too few unclipped
// samples, no exposure variation, a failed or non-monotonic fit) never throws and never yields
// NaN: the result has ok = false, a reason, and the prior response / given exposures.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/photometric/grey_range_advice.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

struct ExposureSweepOptions {
  int max_points = 3000;            // sampled pixel positions (low local gradient)
  int min_valid_grey = 1;           // a sample whose 3x3 neighbourhood holds a value below this
  int max_valid_grey = 254;         //   or above this counts as clipped and is skipped
  double min_unclipped_fraction = 0.05;  // of the sampled positions, for an image to be used
  int min_points = 50;              // points with >= 2 unclipped observations
  double huber_grey = 3.0;          // Huber width in grey levels
  int max_iterations = 100;
  double coefficient_prior_weight = 1e-7;  // per observation, pulls c towards the prior's (residuals are in [0, 1] units)
  ResponseModel prior;              // returned when the input is degenerate; start of the fit
  bool fix_response = false;        // hold f at the prior, estimate exposures (and radiances) only
};

enum class SweepAmbiguityResolution {
  KnownExposureTimes,            // exposures fixed from the given times
  ReferenceImageNormalisation,   // e_ref = 1, gamma pinned only by the basis (weak, see above)
  FixedPriorResponse,            // e_ref = 1, f held at options.prior (fix_response)
  IlluminatorPowerSweep,         // power x exposure known (calibrate_power_sweep)
};
std::string to_string(SweepAmbiguityResolution resolution);

struct ExposureSweepImage {
  double exposure = 0.0;       // given time, or estimated in units of the reference exposure
                               // (0 for an image not used when the exposures are estimated)
  double ratio = 0.0;          // exposure / exposure of the reference image (0 likewise)
  bool used = false;           // took part in the fit
  int unclipped_samples = 0;   // of the sampled positions
  double residual_rms_grey = 0.0;  // of this image's observations in the fit
  // With given exposures: the factor on the image's given exposure (x power for a power sweep)
  // that its own grey values fit best, the fitted response and the points' radiances held (1 when
  // they agree; see reported_exposure_check).
  double brightness_exposure_factor = 1.0;
  bool brightness_disagrees = false;  // named in reported_exposure_check
  std::string note;            // why an image was not used
};

// An image whose brightness disagrees with its given exposure by more than this factor (either
// way), and by more than this many robust standard deviations of the used images' log factors
// about their median, is named in ExposureSweepResult::reported_exposure_check. A late report
// in a sweep of whole stops is off by 2x; the real Canon stack's darkest images, their times
// right, wander by up to 1.18x at half size (where the response basis fits its toe least), so
// steps finer than about a third of a stop go unchecked.
constexpr double kReportedExposureTolerance = 1.25;
constexpr double kReportedExposureOutlierSigmas = 3.0;

struct ExposureSweepResult {
  bool ok = false;
  std::string reason;  // empty when ok; else why the prior was kept
  ResponseModel response;
  std::vector<ExposureSweepImage> images;
  int reference_image = -1;
  SweepAmbiguityResolution resolution = SweepAmbiguityResolution::ReferenceImageNormalisation;
  double residual_rms_grey = 0.0;  // over the used observations, grey levels
  int point_count = 0;
  int observation_count = 0;
  int iterations = 0;
  bool monotonic = true;
  // The grey level (0..255) that 1 % of the fitted observations reach or exceed: above it the
  // response is the basis's continuation, not the data's. With known exposures the fit is exact up
  // to there but the normalisation f(1) = 1 then sets its scale by that continuation (the simulated
  // street's power sweep at 4 ms: observations up to 120, 0.01 grey levels modulo the scale there,
  // 2.6 over all levels; at 12 ms 0.2).
  double highest_grey = 0.0;
  // Power sweep with the ambient term: the median over the points of the ambient irradiance
  // over the lamp's at the weakest lit image (weakest_image).
  bool ambient_modelled = false;
  double ambient_share_at_weakest = 0.0;
  int weakest_image = -1;
  // With given exposures: the images whose brightness_exposure_factor is beyond
  // kReportedExposureTolerance and the sweep's own scatter, and what that means (empty when every
  // used image agrees). A camera that reports its exposure control's value rather than the
  // frame's own exposure (UVC auto exposure read back late, a setting that takes effect frames
  // later) bends the fit this way. Measured against the consensus of the sweep's images: it names
  // the images that disagree, not which side is wrong.
  std::string reported_exposure_check;
};

// The exposure x gain factor that would take highest_grey to kSweepTargetHighestGrey (1 when the sweep
// reached kSweepAdvisedHighestGrey or failed; grey_range_advice.hpp).
double sweep_exposure_factor(const ExposureSweepResult& result);
// What to do when the sweep's observations stop short of the top (empty when they do not).
std::string sweep_range_advice(const ExposureSweepResult& result);

// `images`: 8-bit single-channel images of one size. `exposure_times`: one positive time per image
// (any unit), or nothing to estimate the exposures too.
ExposureSweepResult calibrate_exposure_sweep(const std::vector<cv::Mat>& images,
                                             const std::optional<std::vector<double>>& exposure_times,
                                             const ExposureSweepOptions& options = {});

// An illuminator power sweep: the rig stands still and the lamp steps through its powers. The
// lamp's irradiance is proportional to its power; light it does not give (sky, street lights,
// the tunnel's lamps) adds a radiance A_i per point that scales with the exposure only:
//
//   I_ij / 255 = f(t_j (P_j R_i + A_i)) = f(L_i (q_j + b_i s_j)),
//   q_j = t_j P_j / (t_ref P_ref),  s_j = t_j / t_ref,  b_i = A_i / (P_ref R_i) >= 0
//
// (t_j exposure time x gain, ref the first usable lit image). Without the ambient term
// (model_ambient false) b_i = 0 and a lamp-off image is left out; that is the known-exposure fit
// with t_j P_j as the times, exact when the lamp is the only light and biased otherwise (the
// simulated street under its sky: 55-74 grey levels). With it each point carries log b_i too
// (a 2x2 block in the Schur complement), lamp-off images observe A_i directly, and the response
// is still pinned: with f(0) = 0 only a common scale of L and A keeps the images' grey values,
// the same irradiance scale as without ambient light. A point then needs 3 unclipped images.
struct PowerSweepFrame {
  double power_w = 0.0;   // 0: lamp off
  double exposure = 0.0;  // exposure time x gain, any unit
};
ExposureSweepResult calibrate_power_sweep(const std::vector<cv::Mat>& images, const std::vector<PowerSweepFrame>& frames,
                                          bool model_ambient, const ExposureSweepOptions& options = {});

// The power sweep's log irradiance log X_ij = l_i + log(q_j + b_i s_j) (above) and, with a
// pointer, its derivative by the ambient share b_i.
double power_sweep_log_irradiance(double log_radiance, double ambient, double lamp_scale, double ambient_scale,
                                  double* d_ambient = nullptr);

// The model's prediction f(exp(log_irradiance)) for coefficients c, evaluated as a polynomial in
// u = sqrt(X) (not clamped, so the fit has a gradient past saturation). With a jacobian it also
// gives d/dc1..c4 (entries 0..3) and d/dlog_irradiance (entry 4). Equal to ResponseModel on [0, 1].
double sweep_prediction(const Eigen::Vector4d& c, double log_irradiance,
                        Eigen::Matrix<double, 5, 1>* jacobian = nullptr);

// An exposure-time list such as the MPI HDR sets' shutter.txt: lines "NAME: TIME" where TIME is
// seconds as a number or a fraction "1/250". Lines whose first field does not end in ':' are free
// text and skipped, as are '#' comments. Throws InputError naming the file and line for a data
// line with a missing, non-positive or malformed time, or when no data line exists.
struct NamedExposureTime {
  std::string name;
  double seconds = 0.0;
};
std::vector<NamedExposureTime> read_exposure_times(const std::filesystem::path& file);

}  // namespace nirslam
