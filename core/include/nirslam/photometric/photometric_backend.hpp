#pragma once

// The back end of the online photometric calibration (issue 6; Bergmann, Wang and Cremers,
// "Online photometric calibration of auto exposure video"; the NIR paper's Eq. 2-2 .. 2-7):
// response f (c1..c4, response_model.hpp), vignette V (v1..v3) and keyframe exposures e_i from the
// grey values of tracked points over a window of keyframes.
//
// Point p is one pixel of a tracked patch (kBackendPixels per track, keyframe_selection.hpp),
// observed with grey value I_i^p at radius r_i^p in keyframe i. Its residual (Eq. 2-2):
//
//   r_i^p = G(I_i^p) / (e_i V(r_i^p)) - L_p,       G = 255 f^-1(I / 255)  (grey-level units)
//
// G is f^-1 for the current c: with u = sqrt(X) solving f(u) = I/255, the implicit function
// theorem gives dX/dc_k = -2u h_k(u) / f'(u) (h_k the basis, f' = df/du), which makes the
// Jacobian in c analytic; dr/dv_j = -G r^(2j) / (e V^2) (j = 1..3), dr/de = -G / (e^2 V),
// dr/dL = -1 (photometric_residual() below, tested against numeric differentiation).
//
// Weights: w = w_huber(s) * mu / (mu + |grad I|^2) (Eq. 2-5; the gradient term down-weights pixels
// where a sub-pixel tracking error changes the grey value a lot) * (e_i V f'(X))^2, with
// s = r e_i V f'(X) the residual carried back to grey levels (first order). The last factor is
// ours: unweighted, the radiance-domain energy has a degenerate minimum: a response that is flat
// over the observed grey values and jumps near white makes G(I), hence every residual, as small as
// wanted (f(1) = 1 only pins G at 255), and making every e larger also shrinks every residual.
// Weighted, the cost is the grey-level error of Bergmann et al., whose noise is about constant.
// The factor is held during each Gauss-Newton linearisation (IRLS-like) and evaluated exactly in
// the cost that decides whether a step is accepted.
//
// In the solver the derivatives in v and e are those of the weighted grey-domain residual
// s = (G - e V L) k (k frozen per linearisation) carried to r units, -L r^(2j) / V and -L / e:
// they equal the above only where G = e V L, and with the observed (noisy) G the iteration's
// fixed point is not the cost's minimum (a vignette 2-4x too weak on simulated sequences).
//
// By default (PhotometricResidualForm::PredictedGrey, session 26) the grey-level error is not
// carried back from r but computed as itself, s = I - 255 f(sqrt(e V a L / 255)), and linearised
// at the predicted irradiance e V a L instead of the observed G(I): the same unknowns, steps and
// Schur complement, with r = s / (e V a k) so that dr/dL = -1 and the derivatives in v and e above
// are exact. The observed grey value then enters only as itself, so its noise (sensor, tracking)
// is additive in s; through G(I) it went through the curved G (E[G(I + n)] > G(I) where G is
// convex) and bent the fitted curve (README "Photometric calibration accuracy", session 26).
//
// Solver: Levenberg-Marquardt over the globals x = (c1..c4, v1..v3, free e_i),
//   (J^T W J + lambda diag(J^T W J)) dx = -J^T W r          (Eq. 2-3, 2-4)
// with the radiances eliminated by the Schur complement (each L_p is a 1 x 1 block), and the
// per-point update  dL_p = -(J_p^T W_p r_p + H_pg dx) / ((1 + lambda) J_p^T W_p J_p), which is the
// paper's Eq. 2-7 plus the coupling term H_pg dx of the exact block elimination (the paper
// alternates the two updates; eliminating converges in far fewer iterations because exposure and
// radiance are strongly coupled). A step is accepted only if it lowers the cost and keeps f
// strictly monotonic (f' > 0 at 256 points of u, a dot product each with a tabulated basis
// derivative) and V plausible (positive and not rising towards the rim, VignetteModel::
// is_plausible, unless options.vignette_monotonic is off: a halo factor of a lamp whose beam
// is wider than the lens's vignetting could rise off-centre; then only V > 0 is required); an invalid step is halved (backtracking) before lambda grows, and a
// soft penalty on f' below options.monotonic_margin lets the solver slide along the monotonicity
// boundary instead of stopping at it (a linear response, f' = 2u in u, lies on that boundary).
//
// Multi-start: the cost has local minima in c (a start at gamma stalls ~50 grey levels from a
// linear truth). At the first update that estimates f, every multi_start_every-th update after
// it, and in the batch optimisation, the solver probes a few starts (the current estimate, the
// initial response, the linear response f(X) = X and the basis mean sqrt(X), each with the current
// and with the initial vignette), each with its own radiances and a few LM iterations, and
// continues from the cheapest. (The linear start is the exact linear preset; the other presets
// are not among the starts.) With known exposures there is one more start, fitted to the data
// without the LM's local minima: the log inverse response on the 256 grey levels from
// log G(I) - log L_p = log(e V a) (linear least squares with a smoothness term, Debevec and
// Malik's method, radiances eliminated per point), then the 4 coefficients fitted to it over the
// observed grey range by Gauss-Newton. (Without it, on a room sequence with an 8x exposure swing,
// the LM settled 22 grey levels off in a basin the four fixed starts all fall into.)
//
// Clipped samples (keyframe_selection.hpp's kGreySaturated): a pixel at or above the saturation
// level I_sat says only that its irradiance reached G(I_sat), i.e. e V a L_p >= G(I_sat) for its
// point p. With known exposures the data inside the observed grey range fix G only up to the
// irradiance scale (G = s G_true, L = s L_true fit as well; README "Photometric calibration
// accuracy"), and such a sample bounds s from below wherever its point's radiance is known from
// its normal samples. So each saturated sample of a point with at least
// min_observations_per_point normal samples enters as a one-sided ("hinge") residual
//
//   s_sat = max(0, (G(I_sat) - e V a L) k),     k = dI/dG at I_sat,
//
// zero where the bound holds and the normal samples' Huber cost and weights where it does not
// (clip_bound_residual() below, in r units; where active its Jacobian is that of a normal sample
// with grey value I_sat, which in the solver's grey-domain form is exact because G(I_sat) is not
// a noisy observation). The black side (kGreyDark: e V a L <= G(I_black)) is the mirror image,
// optional (options.black_bounds, off): near black G(I) ~ s G_true(I) as well, so it says little
// about s. Points with only clipped samples are left out (their L is free). The bounds count in
// neither the observed grey range, the Huber width, the radiance initialisation nor the per
// observation weights of the priors (all as without them).
//
// Co-located light: each observation carries the factor a of illumination_factor.hpp (1 when the
// caller gave no distances), and every e V above is e V a: the radiances are then those at each
// point's first observation's distance and power.
//
// Ambiguity: with exposures fixed (reported by the source), f, V and L are determined. Otherwise
// the reference keyframe's exposure (the oldest in the window) is held, which fixes the scale,
// and the gamma (f(X^g), e^g, V^g, L^g fit the data almost equally well: G^g / (e^g V^g) = L^g)
// is pinned by the response basis and the weak prior towards the initial response, and, when
// options.gamma_gauge_weight > 0, by a normalisation: the irradiance of grey level
// options.gamma_gauge_grey, X_gauge(c) = f^-1(grey / 255), is pulled to its value under the
// initial response (for the gamma preset and grey 128: 0.220) by a quadratic penalty of that
// weight per observation (dX/dc = -2u h(u) / f'(u), as in the residual's Jacobian). It is OFF by
// default: measured on room/log without reported exposures, weight 1e3 holds X_gauge within 4 %
// but the fit falls into a worse minimum (response 45 grey levels off, 44 after bringing the truth
// to the same gauge) than without it (14 / 15); 1e5 holds it to 0.1 % and fails (residual 9.8
// grey levels). A penalty inside the LM fights the solver; re-gauging after each solve (mapping
// the solution along the family to X_gauge) is the way to do it, not done yet.
// See online_calibration.hpp.

#include <algorithm>
#include <array>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "nirslam/photometric/beam_halo.hpp"
#include "nirslam/photometric/illumination_factor.hpp"
#include "nirslam/photometric/keyframe_selection.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

// Parameter layout of one residual's Jacobian: c1..c4, v1..v3, e, L.
using PhotometricJacobian = Eigen::Matrix<double, 9, 1>;

// f^-1 for one response: u = sqrt(X) with f(u) = y, from a cubic Hermite table (nodes and their
// slopes) and Newton steps, one except beside a zero slope (exact to about 1e-12). Requires a
// strictly monotonic f.
class InverseResponse {
public:
  explicit InverseResponse(const Eigen::Vector4d& c);
  // u for y in [0, 1] (fraction of full scale).
  double sqrt_irradiance(double y) const;
  const Eigen::Vector4d& coefficients() const { return c_; }

private:
  Eigen::Vector4d c_;
  std::vector<double> table_;  // u at y = i / (size - 1)
  std::vector<double> du_dy_;  // 1 / f'(u) there
};

// r = G(grey) / (exposure V(radius)) - radiance, grey in 0..255. With a jacobian, d r / d(c, v, e, L).
// Also returns G (grey-level units) through `irradiance`, and dI/dG = df/dX (grey levels per
// grey level of irradiance) through `grey_per_irradiance`, when given.
double photometric_residual(const InverseResponse& inverse, const Eigen::Vector3d& v, double exposure,
                            double radiance, double grey, double radius, PhotometricJacobian* jacobian = nullptr,
                            double* irradiance = nullptr, double* grey_per_irradiance = nullptr);

// The residual under a co-located light (illumination_factor.hpp): r = G / (e V a) - L with the
// known factor a = (d_ref / d)^2 (P / P_ref). The Jacobian as above (dr/de = -G / (e^2 V a)); with
// d_residual_d_log_illumination, dr/d(log a) = -G / (e V a), from which dr/dd = -2/d dr/d(log a)
// and dr/dP = 1/P dr/d(log a) follow.
double lit_photometric_residual(const InverseResponse& inverse, const Eigen::Vector3d& v, double exposure,
                                double radiance, double grey, double radius, double illumination,
                                PhotometricJacobian* jacobian = nullptr, double* d_residual_d_log_illumination = nullptr);

// The one-sided residual of a clipped sample (see the header), in the units of
// photometric_residual: for a saturated sample (`saturated`) r = G(clip_grey) / (e V a) - L where
// that is positive (the irradiance e V a L falls short of G(clip_grey)), else 0; for a dark one r
// where it is negative (e V a L above G(clip_grey)), else 0. With a jacobian: that of
// lit_photometric_residual where the bound is violated, zero where it holds.
double clip_bound_residual(const InverseResponse& inverse, const Eigen::Vector3d& v, double exposure, double radiance,
                           double clip_grey, double radius, double illumination, bool saturated,
                           PhotometricJacobian* jacobian = nullptr);

// The residual in the grey domain, predicted against observed: s = grey - 255 f(u),
// u = sqrt(e V a L / 255) (X clamped to [0, 1]), grey in 0..255, a the light's factor (1 without).
// The observed grey value enters only as itself, so its noise is additive in s: no errors in
// variables through G(grey) (see PhotometricResidualForm). With a jacobian, ds / d(c, v, e, L) in
// grey levels: -255 h(u), -k e a L r^2j, -k V a L, -k e V a, with k = f'(u) / (2u) = dI/dG at the
// prediction.
// With clip_noise_grey > 0 the prediction is the expected value of a sample that did not clip
// (PhotometricBackendOptions::clip_noise_grey), and the Jacobian is that of this value.
double predicted_grey_residual(const Eigen::Vector4d& c, const Eigen::Vector3d& v, double exposure, double radiance,
                               double grey, double radius, double illumination = 1.0,
                               PhotometricJacobian* jacobian = nullptr, double clip_noise_grey = 0.0);

// The grey-domain residual with ambient light (PhotometricBackendOptions::lit_ambient): a point
// takes the lamp's light through the halo factor V and the lamp factor a, and light that is not
// the lamp's (sky, street lamps, windows) through the lens alone:
//
//   s = grey - 255 f(u),  u = sqrt(e L (V a + kappa w) / 255),
//
// with kappa the ambient irradiance in units of the lamp's at the window's median point (one
// unknown for the window) and w = W / A_ref the point's known weight: W the lens at the pixel, A_ref
// the lamp's irradiance at the point's reference observation relative to that median (exp of
// log_illumination). With a jacobian, ds / d(c, v, e, L, kappa): -255 h(u), -k e a L r^2j,
// -k L (V a + kappa w), -k e (V a + kappa w), -k e L w, with k = f'(u) / (2u).
using AmbientJacobian = Eigen::Matrix<double, 10, 1>;
double ambient_grey_residual(const Eigen::Vector4d& c, const Eigen::Vector3d& v, double exposure, double radiance,
                             double kappa, double ambient_weight, double grey, double radius, double illumination,
                             AmbientJacobian* jacobian = nullptr, double clip_noise_grey = 0.0);

// A plausible vignette by construction (the back end's "monotone" steps, see
// PhotometricBackendOptions::lit_vignette_steps). With t = r^2, V = 1 + v1 t + v2 t^2 + v3 t^3
// falls (weakly) on [0, 1] exactly when -dV/dt = -(v1 + 2 v2 t + 3 v3 t^2) >= 0 there, and a
// quadratic is non-negative on [0, 1] exactly when it is (a + b t)^2 + c^2 t (1 - t) for some
// q = (a, b, c) (Lukacs' theorem), so
//
//   v1 = -a^2,   v2 = -(2 a b + c^2) / 2,   v3 = (c^2 - b^2) / 3
//
// covers every non-increasing V of the model and nothing else. With dv_dq, dv/dq (3 x 3).
Eigen::Vector3d vignette_from_monotone(const Eigen::Vector3d& q, Eigen::Matrix3d* dv_dq = nullptr);
// A q giving v (the exact inverse for a non-increasing V: a = sqrt(-v1), b a root of
// b^2 + 2 a b + 2 v2 + 3 v3 = 0 with c^2 = -2 v2 - 2 a b >= 0; else the nearest q in least
// squares). |a| and |c| are kept at least `floor`: q = 0 is a stationary point of v(q) (every
// derivative in a and c vanishes there), from which a Gauss-Newton step cannot leave.
Eigen::Vector3d monotone_from_vignette(const Eigen::Vector3d& v, double floor = 0.05);

// How the LM keeps V plausible when options.vignette_monotonic is set.
enum class VignetteSteps {
  // Steps in v; a step that leaves the plausible set is shortened along its own direction to the
  // boundary (bisection). V then stops where it first touches "flat at some radius" and cannot
  // slide along that boundary: a steep halo factor stalls there.
  Bisected,
  // Steps in q of vignette_from_monotone (plausible by construction, only V(1) > 0.05 is
  // bisected), so V moves freely inside the plausible set and along its boundary.
  Monotone,
};

// How an observation's grey value enters the back end's cost (Eq. 2-2 weighted to grey levels).
enum class PhotometricResidualForm {
  // The paper's r = G(I) / (e V a) - L scaled by e V a k, k = dI/dG at the OBSERVED grey value:
  // the grey-level error to first order. Noise in I goes through the curved G and the slope k
  // taken at the noisy value, which biases the fit where G bends (E[G(I + n)] != G(I)).
  ObservedInverse,
  // s = I - 255 f(sqrt(e V a L / 255)) (predicted_grey_residual): the grey-level error itself,
  // the maximum-likelihood form for noise additive in grey levels. Same unknowns, Schur
  // complement and steps; only the point of linearisation (the predicted, not the observed,
  // irradiance) and the residual change.
  PredictedGrey,
};

struct PhotometricBackendOptions {
  ResponseModel initial_response = ResponseModel::from_preset(ResponsePreset::Gamma);
  VignetteModel initial_vignette;
  bool estimate_response = true;
  bool estimate_vignette = true;
  bool trust_known_exposures = true;  // hold e_i of keyframes whose exposure the source reported
  int max_keyframes = 40;             // the online window (oldest dropped)
  int max_stored_keyframes = 400;     // kept for the final (batch) optimisation, evenly thinned
  int max_points = 2400;              // radiance unknowns per optimisation (longest tracks first)
  int min_keyframes = 4;
  int min_points = 60;
  int min_observations_per_point = 2;
  // mu of Eq. 2-5, grey levels^2 per px^2. Small: a pixel's grey value at a tracked point carries
  // an error that grows with the local gradient (KLT slide, sub-pixel interpolation of a sharp
  // texture; test_photometric_diagnostics.cpp variant D: 14 % rms at the true positions where the
  // model data have 0), and noise in G(I) on the points' own observations biases the fitted
  // response towards a flatter log G (errors in variables): on outdoor/gamma G_est / G_true went
  // from 1.41 at grey 16 to 0.96 at 160 with mu = 25, the exposures of the dark ramp frames 12 %
  // off. README "Photometric calibration accuracy": mu 25 / 1 / 0.25 / 0.05 / 0.01 measured, 0.25
  // taken (0.05 about as good on the constant-radiance table but far worse under the lamp, 0.01
  // worse: one row's scale ran off). The weights are not renormalised: the priors are per
  // observation, and weights scaled to mean 1 measured worse (response 6.6 against 4.3 grey levels).
  double gradient_mu = 0.25;
  // The same when the window's observations carry the co-located light's factor. 25 by default:
  // early on (room, distance factor) 0.25..5 measured worse (exposure 20-23 % against 16.7 %).
  // Session 39 measured lower values better for the halo factor (steep samples bent the beam's
  // exponent up): in the 36 lamp runs of config/bench-lamp-colit-calibration.yaml, which now sets
  // 2 (YAML lamp_mode_gradient_mu), the halo factor 0.0204 -> 0.0131, the response 3.31 -> 3.03
  // grey levels, ATE 0.0151 -> 0.0160 m; Table 2's configuration with 2 is not measured enough to
  // change the default (README "Illuminator correction", session 39).
  double lit_gradient_mu = 25.0;
  double huber_k = 2.0;               // Huber width in robust standard deviations of the residual
  PhotometricResidualForm residual_form = PhotometricResidualForm::PredictedGrey;
  PhotometricResidualForm lit_residual_form = PhotometricResidualForm::ObservedInverse;
  double coefficient_prior_weight = 1e-4;  // per observation, on (c - c_initial), in weighted-residual units
  // Per observation, on the squared second differences of log f^-1 over log I (grey levels 5 %
  // apart, up to 255) from log_curvature_overlap_grey below the top of the observed range
  // (BackendStep::grey_high) on: a straight line there is a constant gamma; the weight is scaled
  // by (255 - grey_high) / 255, the part of the scale the data leave open. Inside the observed grey range the data fix G = f^-1 only up to a scale when no frame
  // comes near saturation (G(255) = 255 lies outside; see test_photometric_diagnostics.cpp): the
  // basis then reaches 255 with any bend, and the smoothest continuation of log G is the
  // documented choice among the curves the data cannot tell apart. Used only when some keyframe
  // exposure is known (held); without, the gamma is free too and stays with the basis and prior.
  // Measured on the 16-row constant-radiance table (README), rows meeting response / vignette /
  // exposure median: weight 3: 3 / 6 / 7, 30: 5 / 6 / 6, 100: 6 / 7 / 8, 300: 5 / 5 / 7.
  double log_curvature_weight = 100.0;
  // Where that prior starts, in grey levels below the top of the observed range. 0 since session
  // 26: inside the range the data decide (in the grey-domain form they fix G's shape there to a
  // tenth of a grey level modulo the scale). Measured over three draws with that form (README):
  // 24 (before) response means 6.46 gl, 0 5.73, -24 (a gap above the range) 4.98; linear and gamma
  // rows the same to 0.3 gl, log and filmic rows lower the higher the start (their log G bends up
  // towards white, which the straight continuation misses either way).
  double log_curvature_overlap_grey = 0.0;
  // The same when the window's observations carry the co-located light's factor. 3 until session
  // 27 (100 had made an early `illuminated` bench worse on 7 of 12, parking 0.24 / 0.057 / 0.047
  // -> 0.71 / 0.19 / 0.40 m); with 3 the lamp-lit fits ran off in the irradiance scale (the pipeline's
  // co-lit runs s = 7.9-15, a response flat over most irradiances, as the GUI's demo showed). On
  // session 27's code, Table 2's lamp mode with 3 / 100: 0.0201 / 0.0208 m (from frame 15 0.0150 /
  // 0.0145), its runs' co-lit response 18.45 / 12.23 grey levels (2-4 on 8 of the 9 rows outside
  // the tunnel), halo factor 0.037 / 0.043 (README "Illuminator correction").
  double lit_log_curvature_weight = 100.0;
  // Under the lamp the factor a comes from the odometry's distances, whose log ratios are off by
  // a few per cent (README "Illuminator correction"). An error in log a moves the grey level by
  // dI/d log X times it, which the grey-level residual would count in full; so a steeper G
  // (smaller dI/d log X) made every such error cheaper and the fit ran to G(128) of 2-18 grey
  // levels for the true 56. Each lit observation's residual is therefore normalised by its
  // standard deviation sqrt(noise^2 + (dI/d log X sigma)^2) (relative to the window's mean), with
  // sigma the standard deviation of log a and noise the image's in grey levels: Deming regression
  // instead of least squares in grey levels. Negative: both fitted to each solve's starting
  // residuals (robust variances in 8 bins of dI/d log X); positive: this sigma with
  // lit_image_noise_grey; 0: off. Measured (bench, illuminated mode; README "Illuminator
  // correction"): the final G(128) within 25 grey levels of the truth on 9 of 12 runs (3
  // before), within 10 on 6 (2 before).
  double lit_log_illumination_sigma = -1.0;
  // Once a window carries the lamp's factor, the response is held at the last estimate fitted
  // without it (the first keyframes, before the odometry has distances, where they hardly
  // change); estimated under the factor only when there is no such estimate. The factor's errors
  // in log a pull the response (errors in variables, above), and every estimate moves the frames'
  // correction under the odometry's window. Measured on Table 2's lamp mode from three initial
  // responses, gamma / linear / log (README "Illuminator correction", session 48): geometric mean
  // ATE 0.0237 / 0.0344 / 0.0285 m estimated, 0.0154 / 0.0198 / 0.0199 m held, the response
  // itself further off (mean over the twelve 7.6 / 12.2 / 16.3 grey levels estimated, 17.1 / 21.1
  // / 21.0 held). But from frames 15 and 30, where the rig already moves under its lamp when the
  // first keyframes are fitted as constant radiance, 0.0169 -> 0.0239 m (gamma) and 0.265 ->
  // 0.323 m (linear): over all 84 runs about even (0.0465 / 0.0448 m), so off by default
  // (calibration.lamp_mode_holds_response).
  bool lit_holds_unlit_response = false;
  double lit_image_noise_grey = 1.0;
  // The one-sided residuals of clipped samples (see the header): saturated ones, and dark ones.
  bool saturation_bounds = true;
  bool black_bounds = false;
  // The bound's grey level sits this far inside the clip level (saturation_grey - margin, black_grey
  // + margin): a pixel whose noise-free value is just below the clip level reads above it about half
  // the time, and would violate a bound at the clip level itself by its noise (on the simulator 1-2.5
  // grey levels at full scale, shot noise of a 10000 e- well). Measured on the table with the
  // brighter auto exposure (README "Photometric calibration accuracy"): margin 0 / 3, rows meeting
  // response / vignette / exposure 2 / 7 / 10 and 2 / 8 / 10, bounds violated at the end 30 % and
  // 18 % of them; with the default exposure margin 3 moves no row by more than 0.1 grey levels.
  double clip_bound_margin_grey = 3.0;
  // The noise of a keyframe sample near full scale, grey levels (0: off); only where the residual
  // predicts the grey value (PhotometricResidualForm::PredictedGrey). A sample whose noise takes it
  // to full scale clips and leaves the normal samples, so those left near the top read darker than
  // their irradiance gives (a truncated normal): compared with the plain prediction mu they bend G
  // flat at the top and put the irradiance scale off. With it the prediction is the truncated
  // normal's mean, mu - sigma lambda((255 - mu) / sigma) (lambda the inverse Mills ratio), so the
  // normal samples can reach full scale: the online calibration then keeps them up to grey 254
  // (OnlineCalibrationOptions::keyframe_saturation_level) and bounds the clipped ones at full scale
  // itself, with no margin, where G(255) = 255 ties the scale. Measured on the constant-radiance
  // table (seed 1; README "Photometric calibration accuracy"): with the default auto exposure only
  // the two linear rows that clip change (the street 0.62 -> 0.47, the garage 1.71 -> 1.82 grey
  // levels); with a brighter one (0.55), whose frames clip in 12 of 16 rows, the response over all
  // levels 2.85 -> 2.24 on average, 11 rows under 2 / 10 against 9 (the garage's log 3.56 -> 0.97,
  // filmic 8.47 -> 6.40, the street's filmic 3.58 -> 1.51, the tunnel's 8.19 -> 5.84). On synthetic
  // keyframes with 2 grey levels of noise and a linear response 2.16 -> 0.06 grey levels
  // (test_photometric_backend.cpp). Samples up to 254 without it put the garage's linear row at
  // 18.2 grey levels. The clipped samples' bounds take no correction (they bound the noise-free
  // irradiance); with it there too: 2.23 at sigma 1.5 and 2, 2.83 at 3 (the simulator has 2.5 grey
  // levels per pixel at full scale, a sample is bilinear between four pixels).
  double clip_noise_grey = 1.5;
  double min_exposure_ratio = 1.15;   // max/min exposure in the window below which f is not estimated
  // ... and the fraction of the window's keyframes whose exposure is at least sqrt(min_exposure_ratio)
  // from the window's median below which it is not either. Under the co-located lamp the
  // irradiance changes with every keyframe's distances too, so once the auto exposure settles
  // (at its limit, in the dark) keyframes of one exposure fill the window, and the response's
  // gamma was fitted to the lamp model's misfit alone: over a flat lens with the beam's exponent
  // online, parking 20 W's gamma ran from 2.25 to 2.77 (truth 2.21) as they went from half to all
  // of the 40-keyframe window. Measured (README "Illuminator correction", session 16): at 0.33
  // gamma is held at 2.200 from the 9th keyframe, but parking 20 W is still lost (2.25 m) and the
  // twelve's geometric mean is 0.0509 m against 0.0495 off, so the gamma was not the cause. 0: off.
  double min_exposure_varying_fraction = 0.0;
  double min_radius_span = 0.1;       // V is estimated when min_points / 2 points span this range of radii
  // The straightest continuation of V over t = r^2 beyond the observed radii (the 99th percentile
  // of the observations' radius; tracks seldom reach the image's corners): the second derivative
  // d^2 V / dt^2 = 2 v2 + 6 v3 t at 8 radii from there to 1 is pulled to 0 with this weight times
  // the number of observations and the unobserved part of the radius, as log_curvature_weight
  // does for G. Without it V at the corners is the cubic's extrapolation of the data at mid
  // radius, where biases of a few tenths of a per cent became 14-17 % at r = 1 on the simulated
  // tunnel (README "Photometric calibration accuracy", PhotometricAccuracy.DiagnoseFollowing). Not under the lamp's factor (monotone steps). 0: off.
  // Measured on the 16-row table (rows meeting response / vignette / exposure): 1 gives 5 / 12 / 7
  // (off: 6 / 7 / 8), with the observations following the surface 5 / 13 / 7 (off: 4 / 6 / 7);
  // over three noise draws (seeds 1-3) with following, vignette 0.0039 / 0.0063 / 0.0050 against
  // 0.0084 / 0.0143 / 0.0070 off. It moves the response's irradiance scale where nothing in the
  // frames fixes it (room / log over all levels; modulo the scale unchanged).
  double vignette_rim_curvature_weight = 1.0;
  bool vignette_monotonic = true;     // every accepted V falls (weakly) from the centre to the rim
  // How it stays so (see VignetteSteps), without and with the co-located light's factor in the
  // window's observations. Under the lamp the halo factor V B is steep (the simulator's 30-degree
  // beam times the lens falls to 0.15 at the corner) and bisected steps stall at the boundary
  // (README "Photometric calibration accuracy", co-lit table).
  VignetteSteps vignette_steps = VignetteSteps::Bisected;
  VignetteSteps lit_vignette_steps = VignetteSteps::Monotone;
  // The halo factor as a known lens vignette times the lamp's beam cos(alpha)^m (beam_halo.hpp):
  // when set, the vignette's only unknown is m (starting from its initial exponent), in place of
  // v1..v3 and of the steps above; initial_vignette should be its v at that start.
  std::optional<BeamHalo> beam_halo;
  // With beam_halo: each sample's halo factor as V_lens(r) cos(alpha(r))^m itself (true) or as the
  // sextic closest to it (false; BeamHalo::vignette). The sextic cannot follow a 30-degree beam to
  // the corners (0.0046-0.0051 mean over the image on the bench's camera, README "Illuminator
  // correction", session 40), and the odometry's lamp factor applies the beam's own form.
  bool beam_halo_exact = false;
  // Points whose observations the fitted model cannot explain are left out and the solve goes on
  // without them: after the solve, a point (one grid pixel of a track) whose rms residual over its
  // normal samples exceeds this many robust standard deviations of all the window's residuals
  // (1.4826 median |s|, the noise weights applied) is dropped for this update (the next update
  // starts from every point again). Its radiance absorbs a constant offset, so what is left is
  // change the model does not hold: a grid pixel across a depth edge (its distance is the patch
  // centre's, and the track follows the other side), a specular highlight, a distance the odometry
  // got wrong. Huber weights only shrink such residuals one by one; this takes out the point.
  // Without and with the lamp's factor in the window; 0: off.
  double point_rejection_sigmas = 0.0;
  double lit_point_rejection_sigmas = 0.0;
  // What the rejection measures. Point: the point's own residuals, which carry every error its
  // track shares with its neighbours (a distance ratio the odometry got wrong moves all nine of a
  // track's pixels alike), so with the pipeline's distances whole tracks go. AgainstItsPatch: each
  // residual minus the median of its track's pixels in the same keyframe, taken in log irradiance
  // (s / (dI / d log X)) where a shared factor is a shared offset: what is left is the pixel's
  // own change, which a pixel across a depth edge from the track's surface has (its distance
  // ratio is another surface's, and the parallax slides other surface points under it) and a
  // pixel of the track's surface has not, however wrong the track's distance. Measured in Table
  // 2's lamp runs with config/bench-lamp-colit-calibration.yaml and lit_point_rejection_sigmas 3
  // (36 runs from frames 0 / 15 / 30): the co-lit response's median 3.53 -> 2.88 grey levels and
  // rows under 2 8 -> 11 (the tunnel's 4-4.4 -> 1.1-1.3), but 4 rows above 8 (none before: the
  // response's irradiance scale, its shape in the observed range stays 0.6-1.8), mean 3.21 ->
  // 3.51; halo factor 0.026 -> 0.024; the odometry 0.0159 -> 0.0171 m. Not the default (README
  // "Illuminator correction", session 37).
  enum class Rejection { Point, AgainstItsPatch };
  Rejection rejection = Rejection::Point;
  // A track with any pixel left out goes whole. Worse in the lamp runs (mean 5.58 grey levels
  // over the twelve from frame 0, against 4.22 for the pixels alone).
  bool reject_whole_track = false;
  // Light that is not the lamp's (DESIGN.md's "+ ambient"; the simulator's sky on the street's
  // facades, E_amb (1 + n_z) / 2): in a lamp-lit problem each point's irradiance becomes
  // e L (V a + kappa w) (ambient_grey_residual above), kappa >= 0 one more unknown, held over
  // the updates. A point's ambient share grows with its distance squared (its lamp light falls,
  // the ambient does not), which is what w carries. Without it the street's exact-geometry co-lit
  // calibration puts the beam's exponent 0.3 low (PhotometricAccuracy.CoLitTable) and along the
  // tracks log(L d^2 / (B cos)) changes by -0.16 at the image's centre and -0.35 at its rim over
  // 140 frames (PhotometricAccuracy.SimulatedRadianceFollowsTheLampModel). One ambient radiance per
  // point instead (a 2 x 2 Schur block each) was tried first (session 38): right on synthetic
  // keyframes, but the simulated tracks (4-12 frames) cannot tell it from the radiance and the
  // response's scale ran off (room 5.7 -> 11.3 grey levels, the street's exponent unmoved).
  // Measured (README "Illuminator correction", session 38): on synthetic keyframes exact (test
  // AmbientLightKeepsTheBeamAndResponse); on the co-lit table with the exact geometry and the beam
  // over a flat lens, means over three noise draws, the response 3.61 / 4.97 / 5.12 / 2.05 ->
  // 2.79 / 4.78 / 5.19 / 2.36 grey levels (room / street / garage / tunnel), the halo factor
  // 0.0033 / 0.0096 / 0.0111 / 0.0170 -> 0.0034 / 0.0069 / 0.0110 / 0.0164; in Table 2's lamp runs with
  // config/bench-lamp-colit-calibration.yaml worse (response 3.39 -> 4.55 grey levels, halo
  // factor 0.0142 -> 0.0157, ATE 0.0161 -> 0.0214 m): the pipeline's distance errors go into
  // kappa. Off by default.
  bool lit_ambient = false;
  double convergence_relative = 1e-6; // stop when the cost drops by less than this fraction
  double monotonic_margin = 0.01;     // f'(u) below this (at 256 points) is penalised ...
  double monotonic_penalty_weight = 100.0;  // ... with this weight per observation
  double gamma_gauge_grey = 128.0;    // without known exposures, f^-1 at this grey level is held ...
  double gamma_gauge_weight = 0.0;    // ... at the initial response's value, with this weight per observation (0: off, see above)
  bool multi_start = true;            // probe several starting responses (see above)
  bool data_driven_start = true;      // with known exposures, also start from a direct fit (see above)
  int multi_start_every = 20;         // online updates between two multi-starts
  int multi_start_probe_iterations = 3;
};

struct BackendStep {
  bool ok = false;           // a valid model (possibly unchanged)
  bool updated = false;      // the model changed in this call
  bool converged = false;
  int iterations = 0;
  double cost = 0.0;         // weighted Huber cost per observation, at the end
  double residual_rms = 0.0; // of G(I) - e V L over the inliers, grey levels
  int keyframes = 0;
  int points = 0;
  int observations = 0;       // normal samples
  int points_rejected = 0;    // left out as inconsistent (options.point_rejection_sigmas)
  int clip_bounds = 0;        // one-sided residuals of clipped samples (see the header) ...
  int clip_bounds_violated = 0;  // ... and how many of them do not hold at the end,
  double clip_bound_violation = 0.0;  // by how much (median |s| of those, grey levels)
  bool response_estimated = false;
  bool vignette_estimated = false;
  bool lit = false;            // the observations carried the light's factor (a lamp-lit problem)
  bool multi_started = false;  // several starting responses were probed
  double grey_low = 0.0;     // 1st and 99th percentile of the observed grey values: f is
  double grey_high = 0.0;    // constrained by data only in between (extrapolated outside)
  // 99th percentile of the samples' radius (corner = 1): V is constrained by data only inside
  // (tracks seldom reach the corners); beyond, the model's continuation.
  double radius_high = 0.0;
  // With options.lit_ambient on a lamp-lit problem: kappa, and the median over the points of the
  // ambient's share of their irradiance at their reference observation; 0 otherwise.
  double ambient = 0.0;
  double ambient_share = 0.0;
  std::string status;        // what happened, and why not when nothing was estimated
};

class PhotometricBackend {
public:
  explicit PhotometricBackend(PhotometricBackendOptions options = {});

  void add_keyframe(PhotometricKeyframe keyframe);
  // The stored keyframe of frame `frame_index` takes these tracks' log_illumination where its
  // observation has none (NaN: the distance was unknown then); a known one is never replaced, so
  // a track's factors stay of one distance source. Returns how many observations were filled
  // (0 when the keyframe is not stored, e.g. thinned out, or was made without the light's model).
  std::size_t fill_unknown_illumination(std::int64_t frame_index, std::span<const TrackIllumination> values);
  // LM iterations over the online window (the last max_keyframes keyframes), or over every stored
  // keyframe when `all_stored` (batch: the final optimisation).
  BackendStep optimise(int max_iterations, bool all_stored = false);

  const ResponseModel& response() const { return response_; }
  const VignetteModel& vignette() const { return vignette_; }
  // The beam's exponent m of the halo factor (options.beam_halo); 0 without one.
  double beam_exponent() const { return beam_exponent_; }
  // kappa (options.lit_ambient; see ambient_grey_residual); 0 without.
  double ambient_ratio() const { return ambient_ratio_; }
  // Current exposure of each stored keyframe (frame index -> exposure).
  std::vector<std::pair<std::int64_t, double>> keyframe_exposures() const;
  std::size_t stored_keyframes() const { return keyframes_.size(); }
  const std::deque<PhotometricKeyframe>& keyframes() const { return keyframes_; }
  const PhotometricBackendOptions& options() const { return options_; }
  void reset();

private:
  struct Point {
    int begin = 0, end = 0;  // into observations_
    int track = 0;           // the problem's track (surface) it is a pixel of; a track's points are adjacent
  };
  struct Observation {
    int keyframe = 0;        // into the window's keyframe list
    double grey = 0.0;       // 0..255
    double radius = 0.0;
    double gradient_weight = 1.0;
    double illumination = 1.0;  // the light's factor a relative to the point's first observation
    // 0: a normal sample. +1: saturated, grey is the saturation level and only s <= 0 (e V a L at
    // least G(grey)) is free of cost; -1: dark, only s >= 0 is.
    int bound = 0;
    double ambient_weight = 0.0;  // w of ambient_grey_residual (ambient_)
    // With options.beam_halo_exact: V_lens(radius) and log cos(alpha(radius)) of the beam.
    double lens = 1.0;
    double log_cos = 0.0;
  };
  // The residual s of an observation as the cost sees it: unchanged for a normal sample, 0 where
  // a clipped sample's bound holds.
  static double bounded(const Observation& o, double s) {
    return o.bound == 0 ? s : (o.bound > 0 ? std::max(s, 0.0) : std::min(s, 0.0));
  }
  // One candidate solution: the globals, the radiances and u = sqrt(f^-1(grey)) per observation.
  struct State {
    Eigen::Vector4d c = Eigen::Vector4d::Zero();
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    // v = vignette_from_monotone(q) with monotone steps; (m, 0, 0) with a beam (options.beam_halo),
    // held or estimated, v then the sextic of m.
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    std::vector<double> exposure;  // window keyframes, divided by the median
    std::vector<double> radiance;  // per point
    double ambient = 0.0;          // kappa (ambient_)
    std::vector<double> u;         // per observation, for c
    double cost = 0.0;
  };
  // The halo factor V at an observation under `state`: the sextic v, or with
  // options.beam_halo_exact the beam's own form V_lens cos(alpha)^m, m = state.q[0].
  double halo_at(const State& state, const Observation& o) const;
  void build_problem(const std::vector<int>& window);
  void update_u(State& state) const;
  double data_cost(const State& state, double delta) const;
  // The residual s of observation i of point `point` in grey levels (exposures pre-divided by
  // e_scale): (G - e V a L) k, k = dI/dG, in the observed form; I - 255 f(u) in the predicted one.
  // f'(u) through `slope`, and u where it is linearised (observed or predicted) through `u_at`.
  double scaled_residual(const State& state, std::size_t point, std::size_t i, double& slope, double* u_at = nullptr) const;
  // The lit observations' weight from the uncertain factor a (lit_log_illumination_sigma): the
  // inverse variance of the grey-level residual at u with f'(u) = slope, times model_noise_norm_.
  double model_noise_weight(double u, double slope) const;
  void initialise_radiances(State& state) const;
  // Leaves out the points whose rms residual exceeds `sigmas` robust standard deviations of the
  // residuals (options.point_rejection_sigmas), from points_, observations_ and `state`, unless
  // fewer than options.min_points would stay; returns how many.
  int drop_inconsistent_points(State& state, double sigmas);
  // Each point's rms residual as options.rejection measures it (normal samples; 0 without any),
  // and every such residual's magnitude into abs_s.
  std::vector<double> point_rms_residuals(const State& state, std::vector<double>& abs_s) const;
  // The response fitted directly to the observations of known-exposure keyframes (see above);
  // std::nullopt when too few points or the fit fails.
  std::optional<Eigen::Vector4d> data_driven_response(const std::vector<double>& exposure, const std::vector<bool>& known,
                                                      const Eigen::Vector3d& v, double grey_low, double grey_high,
                                                      const Eigen::Vector4d& start) const;
  PhotometricBackendOptions options_;
  ResponseModel response_;
  VignetteModel vignette_;
  std::deque<PhotometricKeyframe> keyframes_;
  std::int64_t added_ = 0;
  // The problem of the current optimise() call (buffers reused between calls).
  std::vector<int> window_;
  std::vector<Point> points_;
  std::vector<Observation> observations_;
  bool lit_problem_ = false;  // the window's observations carry the light's factor (build_problem)
  bool response_fitted_unlit_ = false;  // some update without the light's factor estimated the response
  bool ambient_ = false;      // ... and the ambient light is modelled (options.lit_ambient)
  double ambient_ratio_ = 0.0;  // kappa, kept between updates
  // e (V a + kappa w) of observation o: what multiplies the radiance.
  double lit_exposure(const State& state, const Observation& o) const;
  // The noise model of a normal sample near full scale (options_.clip_noise_grey); a clipped
  // sample's bound is on its noise-free irradiance and takes none.
  double clip_noise(const Observation& o) const { return o.bound == 0 ? options_.clip_noise_grey : 0.0; }
  bool predicts_grey() const {
    return (lit_problem_ ? options_.lit_residual_form : options_.residual_form) == PhotometricResidualForm::PredictedGrey;
  }
  double model_noise_norm_ = 1.0;  // makes model_noise_weight average 1 at the solve's start
  double model_sigma_log_ = 0.0;    // sigma of log a in this solve (given or estimated)
  double model_noise_grey_ = 1.0;   // image noise in this solve (given or estimated)
  // Fits var(s) = noise^2 + (dI/d log X)^2 sigma^2 to the scaled residuals of `state` (robust
  // variances in bins of dI/d log X); false when the fit is not determined.
  bool estimate_model_noise(const State& state, double& sigma_log, double& noise_grey) const;
  // f^-1 for coefficients c: one solve step asks for the same c several times (the residuals' u,
  // the curvature and gauge priors, at the trial and again when it is linearised), and each
  // table costs about 8000 evaluations of f. Two slots: the current state's c and the trial's.
  const InverseResponse& inverse_response(const Eigen::Vector4d& c) const;
  mutable std::array<std::optional<InverseResponse>, 2> inverse_cache_;
  mutable std::size_t inverse_cache_next_ = 0;
  int updates_since_multi_start_ = 0;
  double beam_exponent_ = 0.0;  // with options_.beam_halo: the current m
  bool response_fitted_ = false;  // f was estimated at least once
};

}  // namespace nirslam
