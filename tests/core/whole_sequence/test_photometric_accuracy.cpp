// Accuracy of the online photometric calibration on simulated sequences against their ground
// truth (issue 6), in the paper's units. PhotometricAccuracy* tests are heavy (rendering plus
// calibration) and are left out of the slow sanitizer runs.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/photometric/calibration_output.hpp"
#include "nirslam/photometric/grey_range_advice.hpp"
#include "nirslam/photometric/illumination_factor.hpp"
#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/pipeline/light_distance_map.hpp"
#include "nirslam/pipeline/slam_pipeline.hpp"
#include "nirslam/sim/scene.hpp"
#include "nirslam/sim/simulator.hpp"
#include "photometric_sequences.hpp"
#include "response_error.hpp"

namespace nirslam {
namespace {

using test_photometric::calibration_sequence;
using test_photometric::co_lit;
using test_photometric::constant_radiance;
using test_photometric::true_light_cosine;

struct AccuracyRun {
  PhotometricErrors errors;
  double mean_grey = 0.0;       // of the sequence, fraction of full scale
  double exposure_span = 0.0;   // max / min true exposure
  double mean_front_end_ms = 0.0;
  double in_range_mean_grey = 0.0;  // response error over the grey levels the fit observed
  double in_range_max_grey = 0.0;
  double gamma_free_mean_grey = 0.0;  // response error after bringing the truth to the estimate's gamma gauge
  double gamma_free_max_grey = 0.0;
  // Over the observed range after the best irradiance scale s (s G_est against G_true): when the
  // frames never reach saturation, the data fix G only up to this scale inside the observed range
  // (G(255) = 255 lies outside it; test_photometric_diagnostics.cpp, variant G, fits exact data
  // with residual 0.00 and a 6-grey-level scale error), so this is what the data determine.
  double scale_free_mean_grey = 0.0;
  double scale_free_max_grey = 0.0;
  double irradiance_scale = 1.0;
  // Frames of the exposure pass whose estimate restarted the chain (with known exposures at the
  // reported value, so such a frame's error is 0 by construction) or kept the last one.
  int restarted_frames = 0;
  int kept_frames = 0;
  // Exposure median relative error on the chain's first-frame scale (errors has it on the
  // reported scale, exposure_scale.hpp).
  double first_frame_exposure_median = 0.0;
  std::shared_ptr<const PhotometricEstimate> estimate;
};

// A sum of four uniforms on [-0.5, 0.5] (roughly normal, variance 1/3: times sqrt(3) for unit
// variance), a fixed function of key.
double uniform_sum_for_key(std::uint64_t key) {
  key = (key ^ (key >> 31)) * 0x9E3779B97F4A7C15ull;
  key ^= key >> 29;
  double n = 0.0;
  for (int i = 0; i < 4; ++i, key = key * 6364136223846793005ull + 1442695040888963407ull)
    n += static_cast<double>(key >> 11) / 9007199254740992.0 - 0.5;
  return n;
}

// Diagnosis (NIRSLAM_PHOTOMETRIC_HELD_PLACEMENT=sigma): the pipeline's held points
// (TrackLightPoints) with exact poses, so their own error is all there is: a track's surface
// point is placed once, on its first pixel's ray at the true distance times exp(sigma n) (n one
// draw per track), and each later frame gets that point's distance from the true lamp. Its error
// reaches the ratio only through the camera's travel (about d_err t / (d_0 d_t)), unlike the
// white noise of NIRSLAM_PHOTOMETRIC_DISTANCE_NOISE. One per pass over the sequence.
struct HeldPlacementEmulation {
  double sigma = 0.0;
  std::unordered_map<std::int64_t, Eigen::Vector3d> points_world;
  // |log(held / true distance at the pixel)| of each later lookup: how far the tracked pixel
  // moves off its first surface point (tracker drift, patches across depth edges).
  std::vector<double> log_errors;
  void print(const char* pass) {
    if (log_errors.empty()) return;
    std::sort(log_errors.begin(), log_errors.end());
    const auto q = [&](double p) { return log_errors[static_cast<std::size_t>(p * static_cast<double>(log_errors.size() - 1))]; };
    std::printf("held points (%s): |log(held / true at the pixel)| median %.4f, 90 %% %.4f, 99 %% %.4f of %zu\n", pass, q(0.5), q(0.9),
                q(0.99), log_errors.size());
  }
};

// Ground-truth light distances of the frame last rendered with depth (the simulator knows them;
// the pipeline hands the odometry's depths the same way).
// With `cosine` also the light's true incidence cos(theta) from the scene's surface normal at the
// pixel (a ray cast per tracked pixel), which the factor then carries (illumination_factor.hpp).
FrameIllumination true_illumination(const Simulator& sim, const SimulatedFrame& f, bool cosine,
                                     HeldPlacementEmulation* held = nullptr) {
  FrameIllumination illumination;
  illumination.light_distance_m = [&sim, &f](const Eigen::Vector2d& pixel) { return sim.light_distance(f.depth, pixel); };
  // Diagnosis: distances scattered like the odometry's (log-normal, sigma from
  // NIRSLAM_PHOTOMETRIC_DISTANCE_NOISE, one draw per frame and 16 px cell).
  if (const char* noise = std::getenv("NIRSLAM_PHOTOMETRIC_DISTANCE_NOISE")) {
    const double sigma = std::atof(noise);
    illumination.light_distance_m = [&sim, &f, sigma](const Eigen::Vector2d& pixel) -> std::optional<double> {
      const auto d = sim.light_distance(f.depth, pixel);
      if (!d) return d;
      const std::uint64_t key = static_cast<std::uint64_t>(f.frame.index) * 1000003u +
                                static_cast<std::uint64_t>(pixel.x() / 16.0) * 1009u + static_cast<std::uint64_t>(pixel.y() / 16.0);
      const double n = uniform_sum_for_key(key);
      return *d * std::exp(sigma * n * std::sqrt(3.0));
    };
  }
  // Diagnosis: a drifting monocular scale, d exp(-drift * frame / 150) (the odometry's scale in the
  // room drifted by about 0.5 in log over 110 frames, README).
  if (const char* drift = std::getenv("NIRSLAM_PHOTOMETRIC_DISTANCE_DRIFT")) {
    const double factor = std::exp(-std::atof(drift) * static_cast<double>(f.frame.index) / 150.0);
    illumination.light_distance_m = [inner = illumination.light_distance_m, factor](const Eigen::Vector2d& pixel) -> std::optional<double> {
      const auto d = inner(pixel);
      if (!d) return d;
      return *d * factor;
    };
  }
  if (held != nullptr) {
    illumination.track_light_distance_m = [&sim, &f, held](std::int64_t track_id, const Eigen::Vector2d& pixel) -> std::optional<double> {
      const Eigen::Vector3d light_offset = sim.options().light_offset_cam;
      if (const auto point = held->points_world.find(track_id); point != held->points_world.end()) {
        const Eigen::Vector3d p_cam = f.T_world_cam.inverse() * point->second;
        if (!(p_cam.z() > 0.0)) return std::nullopt;
        const double distance = (p_cam - light_offset).norm();
        if (held->sigma == 0.0)
          if (const auto truth = sim.light_distance(f.depth, pixel)) held->log_errors.push_back(std::abs(std::log(distance / *truth)));
        return distance;
      }
      const auto d = sim.light_distance(f.depth, pixel);
      const auto ray = sim.camera()->unproject(pixel);
      if (!d || !ray) return std::nullopt;
      const double placed = *d * std::exp(held->sigma * uniform_sum_for_key(static_cast<std::uint64_t>(track_id)) * std::sqrt(3.0));
      held->points_world.emplace(track_id, f.T_world_cam * point_at_light_distance(ray->normalized(), light_offset, placed));
      return placed;
    };
    illumination.light_distance_m = {};  // as in the pipeline: no per-frame lookup once points are held
  }
  // Diagnosis: no distance for a patch whose back-end grid (+-3 px) crosses a depth edge: a
  // second difference of the depth over this many pixels (along x, y and both diagonals) above 2 %
  // of the depth. A plane seen at a grazing angle has none (its inverse depth is affine).
  if (const char* edge = std::getenv("NIRSLAM_PHOTOMETRIC_SKIP_DEPTH_EDGES")) {
    const int reach = std::atoi(edge);
    illumination.light_distance_m = [inner = illumination.light_distance_m, &f, reach](const Eigen::Vector2d& pixel) -> std::optional<double> {
      const int x = static_cast<int>(std::lround(pixel.x())), y = static_cast<int>(std::lround(pixel.y()));
      if (x < reach || y < reach || x + reach >= f.depth.cols || y + reach >= f.depth.rows) return std::nullopt;
      const double rho = 1.0 / f.depth.at<float>(y, x);
      for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{1, -1}}) {
        const double ahead = 1.0 / f.depth.at<float>(y + reach * dy, x + reach * dx);
        const double behind = 1.0 / f.depth.at<float>(y - reach * dy, x - reach * dx);
        if (std::abs(ahead + behind - 2.0 * rho) > 0.02 * rho) return std::nullopt;
      }
      return inner(pixel);
    };
  }
  // Diagnosis: observations where the light grazes left out (the pipeline's lamp_cosine_min; 0.02 here).
  const double min_cosine = std::getenv("NIRSLAM_PHOTOMETRIC_MIN_COSINE") ? std::atof(std::getenv("NIRSLAM_PHOTOMETRIC_MIN_COSINE")) : 0.02;
  if (cosine)
    illumination.light_cosine = [&sim, &f, min_cosine](const Eigen::Vector2d& pixel) -> std::optional<double> {
      const auto cos_theta = true_light_cosine(sim, f.T_world_cam, pixel);
      if (!cos_theta || !(*cos_theta > min_cosine)) return std::nullopt;
      return cos_theta;
    };
  return illumination;
}

// A sequence rendered once for every run on it: a run's two passes (below) and the runs of a test
// that compares settings on the same frames (the renderer was about 60 % of these tests' CPU).
// The frames are kept without their radiance, which no pass reads; with their depth maps when
// a run is to hand the calibration the lamp's true distances.
struct RenderedSequence {
  SimulatorOptions options;
  bool with_depth = false;
  std::vector<SimulatedFrame> frames;
};

RenderedSequence render(const SimulatorOptions& options, bool with_depth) {
  RenderedSequence out{options, with_depth, {}};
  Simulator sim(options);
  while (auto f = sim.next(with_depth)) {
    f->radiance.release();
    out.frames.push_back(std::move(*f));
  }
  return out;
}

// Calibrates online over the sequence, finish(), then estimates every frame's exposure again with
// the final model (front end only), as `nirslam calibrate` does.
// With light_factor the calibration gets the lamp's true distances (the sequence rendered with
// its depth), with light_cosine (or NIRSLAM_PHOTOMETRIC_TRUE_COSINE set) also the true cos(theta).
AccuracyRun run(const RenderedSequence& sequence, bool use_reported_exposures, bool light_factor = false,
                bool light_cosine = false, const std::function<void(OnlineCalibrationOptions&)>& adjust = {}) {
  if (light_factor && !sequence.with_depth) throw std::invalid_argument("run: the lamp's distances need a sequence rendered with depth");
  const SimulatorOptions& sim_options = sequence.options;
  light_cosine |= std::getenv("NIRSLAM_PHOTOMETRIC_TRUE_COSINE") != nullptr;
  OnlineCalibrationOptions options;
  options.background_thread = false;  // deterministic
  options.use_reported_exposures = use_reported_exposures;
  options.correct_images = false;
  // The pipeline's rule: with the lamp's distances, the illuminated mode's own settings.
  if (light_factor) {
    const PipelineOptions lamp_mode;
    options.keyframes_follow_deformation = lamp_mode.lamp_mode_keyframes_follow_surface;
    options.exposure.follow_deformation = lamp_mode.lamp_mode_exposure_follows_surface;
    options.backend.vignette_rim_curvature_weight = lamp_mode.lamp_mode_vignette_rim_curvature_weight;
    options.tracker.skip_coarse_levels_at_border = lamp_mode.lamp_mode_track_near_border;
  }
  if (adjust) adjust(options);  // a test's own settings; the variables below still override them
  if (const char* probe = std::getenv("NIRSLAM_PHOTOMETRIC_PROBE")) options.backend.multi_start_probe_iterations = std::atoi(probe);
  if (const char* gauge = std::getenv("NIRSLAM_PHOTOMETRIC_GAUGE_WEIGHT")) options.backend.gamma_gauge_weight = std::atof(gauge);
  if (std::getenv("NIRSLAM_PHOTOMETRIC_FREE_VIGNETTE") != nullptr) options.backend.vignette_monotonic = false;
  // How V stays plausible (photometric_backend.hpp, VignetteSteps), with and without the lamp's factor.
  if (const char* steps = std::getenv("NIRSLAM_PHOTOMETRIC_VIGNETTE_STEPS")) {
    const VignetteSteps chosen = std::string(steps) == "monotone" ? VignetteSteps::Monotone : VignetteSteps::Bisected;
    options.backend.vignette_steps = options.backend.lit_vignette_steps = chosen;
  }
  if (const char* ncc = std::getenv("NIRSLAM_PHOTOMETRIC_MIN_NCC")) options.tracker.min_reference_ncc = std::atof(ncc);
  if (const char* iso = std::getenv("NIRSLAM_PHOTOMETRIC_CORNER_ISOTROPY")) options.tracker.min_corner_isotropy = std::atof(iso);
  if (const char* gain = std::getenv("NIRSLAM_PHOTOMETRIC_FRAME_GAIN")) options.tracker.frame_pair_gain = std::atoi(gain) != 0;
  // Tracks near the image border refined from the finer pyramid levels (photometric_tracker.hpp).
  if (const char* skip = std::getenv("NIRSLAM_PHOTOMETRIC_BORDER_TRACKS")) options.tracker.skip_coarse_levels_at_border = std::atoi(skip) != 0;
  // The back end's residual form (photometric_backend.hpp, PhotometricResidualForm): "predicted"
  // or "observed", without and (LIT_) with the lamp's factor.
  const auto residual_form = [](const char* name) {
    return std::string(name) == "predicted" ? PhotometricResidualForm::PredictedGrey : PhotometricResidualForm::ObservedInverse;
  };
  if (const char* form = std::getenv("NIRSLAM_PHOTOMETRIC_RESIDUAL")) options.backend.residual_form = residual_form(form);
  if (const char* form = std::getenv("NIRSLAM_PHOTOMETRIC_LIT_RESIDUAL")) options.backend.lit_residual_form = residual_form(form);
  if (const char* mu = std::getenv("NIRSLAM_PHOTOMETRIC_MU")) options.backend.gradient_mu = std::atof(mu);
  if (const char* mu = std::getenv("NIRSLAM_PHOTOMETRIC_LIT_MU")) options.backend.lit_gradient_mu = std::atof(mu);
  if (const char* w = std::getenv("NIRSLAM_PHOTOMETRIC_CURVATURE")) options.backend.log_curvature_weight = std::atof(w);
  if (const char* w = std::getenv("NIRSLAM_PHOTOMETRIC_LIT_CURVATURE")) options.backend.lit_log_curvature_weight = std::atof(w);
  if (const char* g = std::getenv("NIRSLAM_PHOTOMETRIC_CURVATURE_OVERLAP")) options.backend.log_curvature_overlap_grey = std::atof(g);
  // Clipped samples as one-sided constraints (photometric_backend.hpp): off, the black side too,
  // the keyframes' saturation level (online_calibration.hpp).
  if (std::getenv("NIRSLAM_PHOTOMETRIC_NO_CLIP_BOUNDS") != nullptr) options.backend.saturation_bounds = false;
  if (std::getenv("NIRSLAM_PHOTOMETRIC_BLACK_BOUNDS") != nullptr) options.backend.black_bounds = true;
  if (const char* margin = std::getenv("NIRSLAM_PHOTOMETRIC_CLIP_MARGIN")) options.backend.clip_bound_margin_grey = std::atof(margin);
  // 0: the back end without the clip noise (and so the keyframes' samples cut at the tracker's 0.97).
  if (const char* noise = std::getenv("NIRSLAM_PHOTOMETRIC_CLIP_NOISE")) options.backend.clip_noise_grey = std::atof(noise);
  if (const char* level = std::getenv("NIRSLAM_PHOTOMETRIC_KEYFRAME_SATURATION")) options.keyframe_saturation_level = std::atof(level);
  if (const char* w = std::getenv("NIRSLAM_PHOTOMETRIC_RIM_CURVATURE")) options.backend.vignette_rim_curvature_weight = std::atof(w);
  // Inconsistent points left out after each solve (photometric_backend.hpp), without and with the lamp's factor.
  if (const char* k = std::getenv("NIRSLAM_PHOTOMETRIC_POINT_REJECTION")) options.backend.point_rejection_sigmas = std::atof(k);
  if (const char* k = std::getenv("NIRSLAM_PHOTOMETRIC_LIT_POINT_REJECTION")) options.backend.lit_point_rejection_sigmas = std::atof(k);
  if (std::getenv("NIRSLAM_PHOTOMETRIC_REJECT_AGAINST_PATCH") != nullptr)
    options.backend.rejection = PhotometricBackendOptions::Rejection::AgainstItsPatch;
  if (std::getenv("NIRSLAM_PHOTOMETRIC_REJECT_WHOLE_TRACKS") != nullptr) options.backend.reject_whole_track = true;
  // The ambient light beside the lamp's (photometric_backend.hpp, lit_ambient).
  if (std::getenv("NIRSLAM_PHOTOMETRIC_LIT_AMBIENT") != nullptr) options.backend.lit_ambient = true;
  // The distances here are the simulator's, exact: no noise in log a to model (fitted anyway, the
  // model noise takes other errors for it: room d^2 + cos 0.0037 -> 0.0225 vignette, 1.6 -> 2.7 %).
  options.backend.lit_log_illumination_sigma = 0.0;
  if (const char* sigma = std::getenv("NIRSLAM_PHOTOMETRIC_LIT_SIGMA")) options.backend.lit_log_illumination_sigma = std::atof(sigma);
  // Fall-off of the exposure estimator's trust outside the fitted grey range (exposure_estimator.hpp);
  // 1e9 trusts every grey level (as before the weighting).
  if (const char* w = std::getenv("NIRSLAM_PHOTOMETRIC_TRUST_WIDTH")) options.exposure.trust_width_grey = std::atof(w);
  // The exposure estimator's robust mean: Huber width and re-anchoring distance, in robust
  // standard deviations (exposure_estimator.hpp).
  if (const char* k = std::getenv("NIRSLAM_PHOTOMETRIC_EXPOSURE_HUBER")) options.exposure.huber_k = std::atof(k);
  if (const char* k = std::getenv("NIRSLAM_PHOTOMETRIC_EXPOSURE_OUTLIER_SIGMAS")) options.exposure.outlier_sigmas = std::atof(k);
  // The exposure estimator's patches follow the surface's deformation (exposure_estimator.hpp; on
  // by default without the lamp's model; =0 the fixed window).
  if (const char* follow = std::getenv("NIRSLAM_PHOTOMETRIC_FOLLOW_DEFORMATION")) options.exposure.follow_deformation = std::atoi(follow) != 0;
  // The back end's keyframe observations follow the surface (keyframe_selection.hpp; =0 a fixed grid).
  if (const char* follow = std::getenv("NIRSLAM_PHOTOMETRIC_BACKEND_FOLLOW")) options.keyframes_follow_deformation = std::atoi(follow) != 0;
  // The tracker aligns each track's first patch under an affine warp (PhotometricTrackerOptions::
  // align_reference_affine), the deformation the grids then follow.
  if (const char* affine = std::getenv("NIRSLAM_PHOTOMETRIC_TRACK_AFFINE")) options.tracker.align_reference_affine = std::atoi(affine) != 0;
  // The neighbourhood the deformation is fitted over (track_deformation.hpp, 60 px by default).
  if (const char* r = std::getenv("NIRSLAM_PHOTOMETRIC_NEIGHBOUR_RADIUS")) options.tracker.deformation.neighbour_radius_px = std::atof(r);
  // The halo factor as the true lens vignette times the beam, the beam's exponent the only
  // vignette unknown (beam_halo.hpp), from this start; with NIRSLAM_PHOTOMETRIC_BEAM_FLAT_LENS a
  // flat lens instead, as `calibration.lamp_halo: beam` has it (the lens's fall-off goes into m).
  if (const char* start = std::getenv("NIRSLAM_PHOTOMETRIC_BEAM_HALO")) {
    const VignetteModel lens = std::getenv("NIRSLAM_PHOTOMETRIC_BEAM_FLAT_LENS") != nullptr ? VignetteModel{} : sim_options.vignette;
    options.backend.beam_halo = beam_halo_for_camera(*Simulator(sim_options).camera(), lens, std::atof(start));
    options.backend.initial_vignette.v = options.backend.beam_halo->vignette(std::atof(start));
    options.backend.beam_halo_exact = std::getenv("NIRSLAM_PHOTOMETRIC_BEAM_EXACT") != nullptr;
    std::printf("beam halo from m = %s; the simulator's m %.3f\n", start,
                Simulator(sim_options).lighting(sim_options.powers_w.front()).illuminator.beam_exponent());
  }
  // Diagnosis: the back end's initial response (the gamma preset by default), which is one of the
  // multi-start's probes; with another preset the gamma rows do not have their truth among them.
  if (const char* name = std::getenv("NIRSLAM_PHOTOMETRIC_INITIAL_RESPONSE")) {
    const auto preset = parse_response_preset(name);
    if (!preset) throw std::invalid_argument(std::string("NIRSLAM_PHOTOMETRIC_INITIAL_RESPONSE: not a response preset: ") + name);
    options.backend.initial_response = ResponseModel::from_preset(*preset);
  }
  if (std::getenv("NIRSLAM_PHOTOMETRIC_START_TRUE") != nullptr) {  // diagnosis: is it a local minimum?
    options.backend.initial_response = sim_options.response;
    // Under the lamp the halo factor (the vignette the back end estimates then).
    options.backend.initial_vignette = sim_options.powers_w.front() > 0.0 ? Simulator(sim_options).halo_factor() : sim_options.vignette;
    // =multi-start keeps the multi-start's probes (which may leave the true start).
    options.backend.multi_start = std::string(std::getenv("NIRSLAM_PHOTOMETRIC_START_TRUE")) == "multi-start";
  }
  // The response held at the truth, as a sweep gives it (config/bench-lamp-sweep-response.yaml).
  if (std::getenv("NIRSLAM_PHOTOMETRIC_HOLD_RESPONSE") != nullptr) {
    options.backend.initial_response = sim_options.response;
    options.backend.estimate_response = false;
  }
  AccuracyRun out;
  PhotometricGroundTruth truth;
  truth.response = sim_options.response;
  // Under the lamp the back end estimates the halo factor V B (lens vignetting times beam).
  truth.vignette = sim_options.powers_w.front() > 0.0 ? Simulator(sim_options).halo_factor() : sim_options.vignette;
  double e_min = 1e30, e_max = 0.0, front_end = 0.0;
  int frames = 0;
  // The held-placement diagnosis (above); one per pass.
  std::optional<HeldPlacementEmulation> held;
  if (const char* sigma = std::getenv("NIRSLAM_PHOTOMETRIC_HELD_PLACEMENT")) {
    held.emplace();
    held->sigma = std::atof(sigma);
  }
  const Simulator sim(sim_options);  // the camera and the lamp's geometry for the true distances
  {
    OnlinePhotometricCalibration calibration(options);
    for (const SimulatedFrame& f : sequence.frames) {
      Frame frame = f.frame;
      const double e = test_photometric::reported_exposure(frame);
      truth.exposures.emplace_back(frame.index, e);
      e_min = std::min(e_min, e);
      e_max = std::max(e_max, e);
      out.mean_grey += f.mean_grey;
      if (!use_reported_exposures) frame.exposure_ms.reset();
      front_end += (light_factor ? calibration.process(frame, true_illumination(sim, f, light_cosine, held ? &*held : nullptr))
                                 : calibration.process(frame))
                       .front_end_ms;
      ++frames;
    }
    calibration.finish();
    out.estimate = calibration.estimate();
  }
  out.mean_grey /= frames;
  out.exposure_span = e_max / e_min;
  out.mean_front_end_ms = front_end / frames;
  OnlineCalibrationOptions second = options;
  second.run_backend = false;
  second.backend.initial_response = out.estimate->response;
  second.backend.initial_vignette = out.estimate->vignette;
  // The estimate's halo factor as it is: with a beam halo the back end would start from the
  // beam's initial exponent instead (it does not run here).
  second.backend.beam_halo.reset();
  second.initial_grey_range = std::make_pair(out.estimate->grey_low, out.estimate->grey_high);
  // Diagnosis, the front end alone: the exposure pass with the true f and V (any value), or with
  // only one of them (=response, =vignette) and the estimate for the other; =response-weighted:
  // the true f with the estimate's trusted grey range kept (the weights as with the estimate).
  if (const char* part = std::getenv("NIRSLAM_PHOTOMETRIC_EXPOSURE_WITH_TRUTH")) {
    const std::string which = part;
    if (which != "vignette") {
      second.backend.initial_response = truth.response;
      if (which != "response-weighted") second.initial_grey_range.reset();  // the true G holds at every grey level
    }
    if (which != "response" && which != "response-weighted") second.backend.initial_vignette = truth.vignette;
  }
  OnlinePhotometricCalibration exposures(second);
  if (held) {
    held->print("calibration");
    held->points_world.clear();
    held->log_errors.clear();
  }
  for (const SimulatedFrame& f : sequence.frames) {
    Frame frame = f.frame;
    if (!use_reported_exposures) frame.exposure_ms.reset();
    if (light_factor)
      exposures.process(frame, true_illumination(sim, f, light_cosine, held ? &*held : nullptr));
    else
      exposures.process(frame);
  }
  if (held) held->print("exposure pass");
  if (std::getenv("NIRSLAM_PHOTOMETRIC_EXPOSURE_TRACE") != nullptr) {  // diagnosis: estimate / truth per frame
    std::printf("estimate/truth (first = 1), every 5th frame:");
    std::optional<double> first;
    for (const ExposureSample& s : exposures.exposure_history()) {
      const auto it = std::find_if(truth.exposures.begin(), truth.exposures.end(), [&](const auto& p) { return p.first == s.frame_index; });
      if (!s.estimated || it == truth.exposures.end()) continue;
      if (!first) first = *s.estimated / it->second;
      if (s.frame_index % 5 == 0 || s.frame_index < 12) std::printf(" %lld:%.3f(%.2fms)", static_cast<long long>(s.frame_index), *s.estimated / it->second / *first, it->second);
    }
    std::printf("\n");
    const std::vector<double> ge = out.estimate->response.inverse_table(256), gt = truth.response.inverse_table(256);
    std::printf("V_est / V_true (over r = 0):");
    for (double r = 0.0; r <= 1.0; r += 0.1)
      std::printf(" %.1f:%.3f", r, (out.estimate->vignette(r) / truth.vignette(r)) / (out.estimate->vignette(0.0) / truth.vignette(0.0)));
    std::printf("\n");
    std::printf("G_est / G_true at grey 8, 16, .. 248 (over its value at 96):");
    for (int i = 8; i < 256; i += 8)
      std::printf(" %d:%.3f", i, (ge[static_cast<std::size_t>(i)] / gt[static_cast<std::size_t>(i)]) / (ge[96] / gt[96]));
    std::printf("\n");
  }
  for (const ExposureSample& s : exposures.exposure_history()) {
    out.restarted_frames += s.status == ExposureStatus::Restarted;
    out.kept_frames += s.status != ExposureStatus::Restarted && s.status != ExposureStatus::Estimated &&
                       s.status != ExposureStatus::FirstFrame;
  }
  out.errors = compare_with_ground_truth(out.estimate->response, out.estimate->vignette, exposures.exposure_history(),
                                         truth, sim_options.width, sim_options.height);
  {  // The chain's own scale (its first frame's reported exposure), as before exposure_scale.hpp.
    std::vector<ExposureSample> chain = exposures.exposure_history();
    for (ExposureSample& s : chain) s.reported.reset();
    out.first_frame_exposure_median = compare_with_ground_truth(out.estimate->response, out.estimate->vignette, chain, truth,
                                                                sim_options.width, sim_options.height)
                                          .exposure_median_relative;
  }
  {
    const std::vector<double> estimated = out.estimate->response.inverse_table(256);
    const std::vector<double> expected = truth.response.inverse_table(256);
    int n = 0;
    for (int i = static_cast<int>(std::ceil(out.estimate->grey_low)); i <= static_cast<int>(out.estimate->grey_high); ++i, ++n) {
      const double d = std::abs(estimated[static_cast<std::size_t>(i)] - expected[static_cast<std::size_t>(i)]);
      out.in_range_mean_grey += d;
      out.in_range_max_grey = std::max(out.in_range_max_grey, d);
    }
    if (n > 0) out.in_range_mean_grey /= n;
    const auto modulo_scale = test_photometric::response_error_modulo_scale(out.estimate->response, truth.response,
                                                                            out.estimate->grey_low, out.estimate->grey_high);
    out.irradiance_scale = modulo_scale.irradiance_scale;
    out.scale_free_mean_grey = modulo_scale.mean_grey;
    out.scale_free_max_grey = modulo_scale.max_grey;
    // Without known exposures the gamma is a normalisation (photometric_backend.hpp): the truth's
    // G^g with g matching the two curves at the gauge grey level is what the data determine.
    const double y = 128.0 / 255.0;
    const double g = std::log(out.estimate->response.inverse(y)) / std::log(truth.response.inverse(y));
    for (std::size_t i = 0; i < 256; ++i) {
      const double d = std::abs(estimated[i] - 255.0 * std::pow(expected[i] / 255.0, g));
      out.gamma_free_mean_grey += d / 256.0;
      out.gamma_free_max_grey = std::max(out.gamma_free_max_grey, d);
    }
  }
  return out;
}

AccuracyRun run(const SimulatorOptions& sim_options, bool use_reported_exposures, bool light_factor = false,
                bool light_cosine = false, const std::function<void(OnlineCalibrationOptions&)>& adjust = {}) {
  return run(render(sim_options, light_factor), use_reported_exposures, light_factor, light_cosine, adjust);
}

void print(const char* label, const AccuracyRun& r) {
  std::printf("%-16s span %4.1fx | response %5.2f / %6.2f gl (observed %3.0f-%3.0f: %5.2f / %6.2f) | vignette %.4f / %.4f | "
              "exposure %.3f / %.3f ms, median %.2f %% | %s\n",
              label, r.exposure_span, r.errors.response_mean_grey, r.errors.response_max_grey, r.estimate->grey_low,
              r.estimate->grey_high, r.in_range_mean_grey, r.in_range_max_grey, r.errors.vignette_mean,
              r.errors.vignette_max, r.errors.exposure_mean_ms, r.errors.exposure_max_ms,
              100.0 * r.errors.exposure_median_relative, r.estimate->status.c_str());
  std::printf("%-16s observed range modulo the irradiance scale (s = %.3f): %5.2f / %6.2f gl; exposure pass: %d frames "
              "restarted, %d kept; exposure max %.2f %%, median on the first frame's scale %.2f %%, aligned by one "
              "scale %.2f %%\n",
              label, r.irradiance_scale, r.scale_free_mean_grey, r.scale_free_max_grey, r.restarted_frames, r.kept_frames,
              100.0 * r.errors.exposure_max_relative, 100.0 * r.first_frame_exposure_median,
              100.0 * r.errors.exposure_median_relative_aligned);
  if (r.estimate->beam_exponent) std::printf("%-16s beam exponent m %.3f\n", label, *r.estimate->beam_exponent);
  if (const std::optional<GreyRangeAdvice> advice = online_grey_range_advice(*r.estimate))
    std::printf("%-16s advice: images %.2fx brighter (the samples' top at grey %.0f)\n", label, advice->exposure_factor,
                advice->highest_grey);
  if (r.estimate->ambiguity == AmbiguityResolution::Normalisation)
    std::printf("%-16s response modulo gamma %5.2f / %6.2f gl (%s)\n", label, r.gamma_free_mean_grey,
                r.gamma_free_max_grey, r.estimate->ambiguity_detail.c_str());
}

TEST(PhotometricAccuracy, RoomConstantRadianceKnownExposures) {
  const AccuracyRun r = run(constant_radiance(sim::SceneKind::Room, ResponsePreset::Log, 150), true);
  print("room log known", r);
  EXPECT_GT(r.mean_grey, 0.2);  // well exposed: auto exposure reached its target
  EXPECT_LT(r.mean_grey, 0.5);
  EXPECT_GT(r.exposure_span, 1.5);
  EXPECT_EQ(r.estimate->ambiguity, AmbiguityResolution::KnownExposures);
  // What the frames determine is pinned: the room never gets brighter than grey 144-150 (auto
  // exposure keeps it mid-grey), so above that G is the straightest continuation of log G, and
  // with it the irradiance scale s (the factor between the estimated and the true G over the
  // observed range) is a normalisation, not a measurement. The log curve's log G bends up
  // towards white, so a straight continuation puts s below 1. Measured over three noise draws
  // (NIRSLAM_PHOTOMETRIC_SEED=1 / 2 / 3, this test's printout) since session 26 (the back end's
  // residual in the grey domain, PhotometricResidualForm::PredictedGrey, the straightness prior
  // from the top of the observed range): s 0.730 / 0.719 / 0.752, modulo s 0.05 / 0.07 / 0.07
  // grey levels (max 0.36 / 0.44 / 0.50), vignette 0.0037 / 0.0028 / 0.0031, exposure median
  // 2.19 / 0.78 / 0.50 % (max over the frames 3.73 / 2.09 / 1.37 %); over all levels 14.6 / 15.2
  // / 13.2 grey levels (max 29-30), which is s. Before (the observed form, whose noise bias
  // happened to lift s on this curve): s 0.943 / 0.936 / 0.918, modulo s 0.06 / 0.02 / 0.23 (max
  // 0.09 / 0.04 / 0.63), over all levels 3.56 / 3.77 / 4.01, vignette 0.0021-0.0023, exposure
  // 1.84 / 0.68 / 0.34 %. The response over all levels is no longer asserted here (the straight
  // continuation is right for linear and gamma curves, OutdoorGammaKnownExposures pins one); the
  // exposure bound is 2.5 % for seed 1's 2.19 % (not understood; not the patches brighter than
  // grey 144, read through the continuation: the exposure estimator's trust fall-off outside the
  // fitted range at 2 / 8 / unlimited grey levels gives 2.03 / 2.19 / 1.91 %).
  EXPECT_GT(r.irradiance_scale, 0.65);
  EXPECT_LT(r.irradiance_scale, 1.05);
  EXPECT_LT(r.scale_free_mean_grey, 0.2);
  EXPECT_LT(r.scale_free_max_grey, 1.0);
  EXPECT_LT(r.errors.vignette_mean, 0.005);
  EXPECT_LT(r.errors.exposure_median_relative, 0.025);
}

// The row whose exposure error was explained (README "Photometric calibration accuracy"): with
// gradient_mu 25 the fitted G had a flatter log G than the truth (G_est / G_true 1.41 at grey 16,
// 0.96 at 160, relative to grey 96), and the dark frames of the auto exposure's ramp were read
// through it: every later frame 12 % off the first. Measured with gradient_mu 0.25 and
// log_curvature_weight 100 (this test's printout): response 1.51 / 3.53 grey levels, vignette
// 0.0058, exposure median 2.95 % (curvature weight 3: 1.97 / 4.89, 0.0079, 3.51 %; mu 25: 6.76 /
// 17.46, 0.0048, 12.1 %). That ramp's error remains (the first frames' ratio to the rest) but
// is no longer every frame's: on the reported scale (exposure_scale.hpp) with the exposure
// patches following the surface, exposure median 0.97 / 0.61 / 0.48 % over seeds 1 / 2 / 3
// (the chain's first-frame scale 4.24 % in seed 1), so the target (< 2 %) is asserted.
// Since session 26 (the residual in the grey domain, PhotometricResidualForm::PredictedGrey) every
// target of issue 6 holds here over all levels, in every draw: response 0.40 / 0.25 / 0.76 grey
// levels (max 1.02 / 0.69 / 1.77; s 0.990 / 0.994 / 0.982; modulo s 0.03 / 0.07 / 0.02), vignette
// 0.0031 / 0.0032 / 0.0031, exposure median 0.70 / 0.71 / 0.51 % (seeds 1 / 2 / 3); before:
// 0.94 grey levels over the draws' median, vignette 0.0057.
TEST(PhotometricAccuracy, OutdoorGammaKnownExposures) {
  const AccuracyRun r = run(constant_radiance(sim::SceneKind::Outdoor, ResponsePreset::Gamma, 150), true);
  print("outdoor gamma", r);
  EXPECT_LT(r.errors.response_mean_grey, 1.5);
  EXPECT_LT(r.errors.response_max_grey, 3.5);
  EXPECT_LT(r.scale_free_mean_grey, 0.2);
  EXPECT_LT(r.errors.vignette_mean, 0.005);
  EXPECT_LT(r.errors.exposure_median_relative, 0.02);
}

TEST(PhotometricAccuracy, RoomConstantRadianceNormalisation) {
  const AccuracyRun r = run(constant_radiance(sim::SceneKind::Room, ResponsePreset::Log, 150), false);
  print("room log normalised", r);
  EXPECT_EQ(r.estimate->ambiguity, AmbiguityResolution::Normalisation);
  EXPECT_TRUE(std::isfinite(r.errors.response_mean_grey));
  // The result says how (un)determined the gamma is. Measured: response 19.2 / 75.7 grey levels,
  // 19.4 after bringing the truth to the estimate's gamma, exposure median 32 % (the exposures
  // inherit the gamma error as e^g; with gradient_mu 25: 16.1 / 61.2, 16.5, 39 %; before the back
  // end's G-domain Jacobian 13.5-14.5, 14.6-14.9 and 136-164 %): far from the targets, which need reported exposures or a power-sweep
  // response here. With the gauge penalty of
  // photometric_backend.hpp (NIRSLAM_PHOTOMETRIC_GAUGE_WEIGHT=1e3) it is worse: 45 grey levels.
  EXPECT_NE(r.estimate->ambiguity_detail.find("gamma NOT determined"), std::string::npos) << r.estimate->ambiguity_detail;
  EXPECT_TRUE(std::isfinite(r.gamma_free_mean_grey));
  EXPECT_TRUE(r.estimate->response.is_monotonic());
}

// Issue 8, calibration side: under the co-located lamp the (d_ref/d)^2 (P/P_ref) factor from the
// true distances. Measured on room/log (known exposures, this test's printout): without the factor
// response 54.6 grey levels, halo factor 0.188 against V B, exposure median 47.9 %; with it 5.75
// (2.32 in the observed range 9-167), 0.0170 and 3.03 %, residual 1.96 against 4.80 grey levels.
// Before the back end's monotone vignette steps (VignetteSteps::Bisected under the lamp too) the
// factor gave 12.1, 0.105 and 16.7 %: the steep halo stalled on the plausibility boundary.
// Exposures on the reported scale (exposure_scale.hpp, session 25): without the factor 21.4 %,
// with it 0.94 % (on the chain's first-frame scale 66.8 % and 3.03 %).
TEST(PhotometricAccuracy, RoomCoLitDistanceFactor) {
  const RenderedSequence sequence = render(co_lit(sim::SceneKind::Room, ResponsePreset::Log, 150), true);
  const AccuracyRun plain = run(sequence, true, false);
  const AccuracyRun lit = run(sequence, true, true);
  print("room co-lit", plain);
  print("room co-lit+d^2", lit);
  EXPECT_LT(lit.errors.exposure_median_relative, 0.04);
  EXPECT_LT(lit.errors.vignette_mean, 0.025);
  EXPECT_LT(lit.in_range_mean_grey, 3.2);
  EXPECT_LT(lit.errors.response_mean_grey, 7.5);
  EXPECT_LT(lit.errors.exposure_median_relative, 0.1 * plain.errors.exposure_median_relative);
  EXPECT_LT(lit.errors.vignette_mean, 0.15 * plain.errors.vignette_mean);
  EXPECT_LT(lit.estimate->residual_rms, 0.5 * plain.estimate->residual_rms);
}

// The same with the light's true incidence cos(theta) in the factor as well (surface normals from
// the scene; the pipeline's plane fits can hand it on, PipelineOptions::lamp_cosine_to_calibration).
// Then the room meets issue 6's halo and exposure targets. Measured (this test's printout): halo
// factor 0.0037 (< 0.005), exposure median 1.62 % (< 2 %; 1.37 % on the reported scale,
// exposure_scale.hpp); the response is 0.76 grey levels off
// modulo the irradiance scale in the observed range but 12.0 over all levels (s = 1.43: the frames
// never reach saturation, so the scale is the documented normalisation, not data; README).
TEST(PhotometricAccuracy, RoomCoLitDistanceAndCosine) {
  const AccuracyRun lit = run(co_lit(sim::SceneKind::Room, ResponsePreset::Log, 150), true, true, true);
  print("room co-lit+d^2+cos", lit);
  EXPECT_LT(lit.errors.vignette_mean, 0.005);
  EXPECT_LT(lit.errors.exposure_median_relative, 0.02);
  EXPECT_LT(lit.scale_free_mean_grey, 1.2);
}

// Issue 8, calibration side, session 30: with the simulator's exact distances and cosines the
// lamp-lit back end still missed the co-lit targets (README "Illuminator correction", session
// 29), most of all through grid pixels that see something other than one surface point (a depth
// edge under the 3 x 3 grid). Leaving out the points whose rms residual exceeds 2 robust standard
// deviations after each solve (PhotometricBackendOptions::lit_point_rejection_sigmas), with the
// grey-domain residual, needs no depth edges. Measured (gamma response, this test's printout):
// room response mean 8.90 -> 2.47 grey levels, halo factor 0.0099 -> 0.0046, exposure median
// 0.92 -> 1.59 %; tunnel 7.32 -> 2.07, 0.0180 -> 0.0088, 2.25 -> 3.56 % (the exposures do not
// gain: not understood). With the observed form (the lamp mode's default) the rejection helps the
// halo factor only (room 0.0226 -> 0.0078 at 2 sigmas, response 10.2 -> 12.0).
TEST(PhotometricAccuracy, CoLitInconsistentPointsLeftOut) {
  for (const sim::SceneKind scene : {sim::SceneKind::Room, sim::SceneKind::Tunnel}) {
    const auto settings = [](double sigmas) {
      return [sigmas](OnlineCalibrationOptions& options) {
        options.backend.lit_residual_form = PhotometricResidualForm::PredictedGrey;
        options.backend.lit_point_rejection_sigmas = sigmas;
      };
    };
    const RenderedSequence sequence = render(co_lit(scene, ResponsePreset::Gamma, 150), true);
    const AccuracyRun kept = run(sequence, true, true, true, settings(0.0));
    const AccuracyRun left_out = run(sequence, true, true, true, settings(2.0));
    const std::string name(sim::to_string(scene));
    print((name + " all points").c_str(), kept);
    print((name + " left out").c_str(), left_out);
    EXPECT_NE(left_out.estimate->status.find("inconsistent points left out"), std::string::npos) << left_out.estimate->status;
    EXPECT_LT(left_out.errors.response_mean_grey, 0.5 * kept.errors.response_mean_grey) << name;
    EXPECT_LT(left_out.errors.vignette_mean, 0.6 * kept.errors.vignette_mean) << name;
    EXPECT_LT(left_out.errors.response_mean_grey, 3.5) << name;
    EXPECT_LT(left_out.errors.vignette_mean, scene == sim::SceneKind::Room ? 0.0065 : 0.012) << name;
    EXPECT_LT(left_out.errors.exposure_median_relative, scene == sim::SceneKind::Room ? 0.025 : 0.05) << name;
  }
}

// NIRSLAM_PHOTOMETRIC_ROWS=outdoor,tunnel: only the table rows whose label contains one of them.
bool wanted_row(const std::string& label) {
  const char* rows = std::getenv("NIRSLAM_PHOTOMETRIC_ROWS");
  if (rows == nullptr) return true;
  const std::string list = rows;
  for (std::size_t a = 0; a <= list.size();) {
    const std::size_t b = std::min(list.find(',', a), list.size());
    if (b > a && label.find(list.substr(a, b - a)) != std::string::npos) return true;
    a = b + 1;
  }
  return false;
}

// The co-lit table: 4 scenes, the log response (NIRSLAM_PHOTOMETRIC_COLIT_RESPONSE=gamma, ... for
// another), without and with the light's distance factor (true distances from the simulator;
// NIRSLAM_PHOTOMETRIC_TRUE_COSINE=1 adds the true cos(theta)). NIRSLAM_PHOTOMETRIC_TABLE=colit to run it.
TEST(PhotometricAccuracy, CoLitTable) {
  if (std::getenv("NIRSLAM_PHOTOMETRIC_TABLE") == nullptr || std::string(std::getenv("NIRSLAM_PHOTOMETRIC_TABLE")) != "colit")
    GTEST_SKIP() << "set NIRSLAM_PHOTOMETRIC_TABLE=colit";
  ResponsePreset response = ResponsePreset::Log;
  if (const char* name = std::getenv("NIRSLAM_PHOTOMETRIC_COLIT_RESPONSE")) {
    const auto parsed = parse_response_preset(name);
    ASSERT_TRUE(parsed.has_value()) << "NIRSLAM_PHOTOMETRIC_COLIT_RESPONSE: not a response preset: " << name;
    response = *parsed;
  }
  for (const sim::SceneKind scene : {sim::SceneKind::Room, sim::SceneKind::Outdoor, sim::SceneKind::Parking, sim::SceneKind::Tunnel}) {
    std::optional<RenderedSequence> sequence;  // one render for both rows of a scene
    for (const bool factor : {false, true}) {
      const std::string label = std::string(sim::to_string(scene)) + " " + std::string(to_string(response)) + (factor ? " +d^2" : " plain");
      if (!wanted_row(label)) continue;
      if (!sequence) sequence = render(co_lit(scene, response, 150), true);
      const AccuracyRun r = run(*sequence, true, factor);
      print(label.c_str(), r);
    }
  }
}

// Does the simulator's radiance follow the lamp model the calibration fits, L = rho B(alpha)
// cos(theta) / d^2? Surface points from the first frame's depths, followed through the co-lit
// sequence without its ambient light (projected, kept where the depth map agrees): every 10th
// frame the median change of log(L d^2 / (B cos)) since the first frame, for the image's centre
// (radius < 0.5) and the rest. Measured: within 0.003 on all four scenes. With the scene's ambient
// light (DESIGN.md's "+ ambient", which the calibration does not model): the street's by frame
// 140 -0.16 at the centre and -0.35 at the rim (its facades far off take much of their light
// from the dusk sky), parking's and the tunnel's -0.014 / -0.013 (NIRSLAM_PHOTOMETRIC_RADIANCE_PROBE=scene
// runs one scene with and without). So with the simulator's exact geometry the lamp-lit
// calibration's misfit (README "Illuminator correction", session 29) is not the lamp model's.
TEST(PhotometricAccuracy, SimulatedRadianceFollowsTheLampModel) {
  const char* only = std::getenv("NIRSLAM_PHOTOMETRIC_RADIANCE_PROBE");
  for (const sim::SceneKind scene : {sim::SceneKind::Room, sim::SceneKind::Outdoor, sim::SceneKind::Parking, sim::SceneKind::Tunnel})
   for (const bool ambient : {false, true}) {
    if (only != nullptr && std::string(only) != sim::to_string(scene)) continue;
    if (ambient && scene != sim::SceneKind::Outdoor && only == nullptr) continue;  // a few % elsewhere
    SimulatorOptions options = co_lit(scene, ResponsePreset::Gamma, 150);
    options.ambient_irradiance = ambient ? std::nullopt : std::optional<double>(0.0);
    Simulator sim(options);
    const sim::Illuminator light = sim.lighting(options.powers_w.front()).illuminator;
    // log(L d^2 / (B cos)) of a surface point in frame f, where it is seen.
    const auto model_log = [&](const SimulatedFrame& f, const Eigen::Vector3d& p_world,
                               Eigen::Vector2d* pixel_out) -> std::optional<double> {
      const Eigen::Vector3d p_cam = f.T_world_cam.inverse() * p_world;
      if (!(p_cam.z() > 0.05)) return std::nullopt;
      const auto pixel = sim.camera()->project(p_cam);
      if (!pixel) return std::nullopt;
      const int x = static_cast<int>(std::lround(pixel->x())), y = static_cast<int>(std::lround(pixel->y()));
      if (x < 2 || y < 2 || x >= f.radiance.cols - 2 || y >= f.radiance.rows - 2) return std::nullopt;
      if (std::abs(f.depth.at<float>(y, x) - p_cam.z()) > 0.01 * p_cam.z()) return std::nullopt;  // hidden
      const auto cos_theta = true_light_cosine(sim, f.T_world_cam, *pixel);
      if (!cos_theta || !(*cos_theta > 0.05)) return std::nullopt;
      const Eigen::Vector3d from_light = p_cam - options.light_offset_cam;
      const double alpha = std::acos(std::clamp(from_light.normalized().z(), -1.0, 1.0));
      const double L = f.radiance.at<float>(y, x);
      if (!(L > 0.0)) return std::nullopt;
      *pixel_out = *pixel;
      return std::log(L * from_light.squaredNorm() / (light.beam(alpha) * *cos_theta));
    };
    const auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      return v[v.size() / 2];
    };
    std::vector<Eigen::Vector3d> points;
    std::vector<double> first;
    int frame = 0, checked = 0;
    double largest_change = 0.0;
    while (auto f = sim.next(true)) {
      if (frame == 0) {
        for (int y = 8; y < f->depth.rows - 8; y += 6)
          for (int x = 8; x < f->depth.cols - 8; x += 6) {
            const double z = f->depth.at<float>(y, x);
            const auto ray = sim.camera()->unproject(Eigen::Vector2d(x, y));
            if (!(z > 0.0) || !ray) continue;
            const Eigen::Vector3d p_world = f->T_world_cam * ((z / ray->z()) * *ray);
            Eigen::Vector2d pixel;
            if (const auto m = model_log(*f, p_world, &pixel)) {
              points.push_back(p_world);
              first.push_back(*m);
            }
          }
        ASSERT_GT(points.size(), 500u) << sim::to_string(scene);
      } else if (frame % 10 == 0) {
        std::vector<double> centre, rim;
        for (std::size_t i = 0; i < points.size(); ++i) {
          Eigen::Vector2d pixel;
          const auto m = model_log(*f, points[i], &pixel);
          if (!m) continue;
          const double r = VignetteModel::radius(pixel.x(), pixel.y(), f->radiance.cols, f->radiance.rows);
          (r < 0.5 ? centre : rim).push_back(*m - first[i]);
        }
        for (const auto* part : {&centre, &rim}) {
          if (part->size() < 50) continue;
          ++checked;
          largest_change = std::max(largest_change, std::abs(median(*part)));
          if (!ambient) {
            EXPECT_LT(std::abs(median(*part)), 0.03) << sim::to_string(scene) << " frame " << frame;
          }
        }
        std::printf("%s%s frame %3d: log(L d^2 / (B cos)) change, centre %+.4f over %zu points, rim %+.4f over %zu\n",
                    std::string(sim::to_string(scene)).c_str(), ambient ? " + ambient" : "", frame, centre.empty() ? 0.0 : median(centre), centre.size(),
                    rim.empty() ? 0.0 : median(rim), rim.size());
      }
      ++frame;
    }
    EXPECT_GE(checked, 6) << sim::to_string(scene) << ": the points left the view too early to say";
    // The street's dusk sky is not in the model the calibration fits: its facades far off take
    // most of their light from it.
    if (ambient && scene == sim::SceneKind::Outdoor) {
      EXPECT_GT(largest_change, 0.1);
    }
  }
}

// The full table: 4 scenes x 4 response presets (NIRSLAM_PHOTOMETRIC_TABLE=1 to run it).
TEST(PhotometricAccuracy, Table) {
  // NIRSLAM_PHOTOMETRIC_ROWS=outdoor,tunnel: only these rows (wanted_row).
  if (std::getenv("NIRSLAM_PHOTOMETRIC_TABLE") == nullptr) GTEST_SKIP() << "set NIRSLAM_PHOTOMETRIC_TABLE=1";
  const std::string which = std::getenv("NIRSLAM_PHOTOMETRIC_TABLE");
  if (which == "colit") GTEST_SKIP() << "the co-lit table is CoLitTable";
  const bool known = which != "normalised";
  for (const sim::SceneKind scene : {sim::SceneKind::Room, sim::SceneKind::Outdoor, sim::SceneKind::Parking, sim::SceneKind::Tunnel})
    for (const ResponsePreset preset : {ResponsePreset::Linear, ResponsePreset::Gamma, ResponsePreset::Log, ResponsePreset::Filmic}) {
      const std::string label = std::string(sim::to_string(scene)) + " " + std::string(to_string(preset));
      if (!wanted_row(label)) continue;
      const AccuracyRun r = run(constant_radiance(scene, preset, 150), known);
      print(label.c_str(), r);
    }
}

}  // namespace
}  // namespace nirslam
