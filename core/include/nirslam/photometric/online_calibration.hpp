#pragma once

// Online photometric calibration (issue 6): the front end (gain-robust KLT, per-frame exposure,
// corrected image) on the caller's thread, the back end (response, vignette, keyframe exposures;
// photometric_backend.hpp) on a background thread over keyframes.
//
// Threads. process() runs on one caller thread (the worker's pipeline thread). Keyframes go to the
// back end through a bounded queue: process() never waits for the back end; when the queue is
// full the oldest keyframe is dropped and counted (keyframes_dropped()). The back end publishes
// each new model as an immutable PhotometricEstimate (a shared_ptr swapped under a mutex that
// guards only the pointer; libstdc++ 12's atomic<shared_ptr> trips ThreadSanitizer), which
// estimate() returns from any thread; process() picks a new model version up at the start of the
// next frame and hands it to the exposure estimator (which then restarts its anchor chain). reset()
// and finish() are called on the caller's thread and wait for the back end.
//
// Ambiguity (DESIGN.md, "The photometric model"): how gamma and scale were fixed is reported in
// every estimate:
//  - KnownExposures: the source reports exposure time (x gain); the back end holds keyframe
//    exposures at those values, so f, V and the radiances are determined. The per-frame exposures
//    are still the front end's estimates, normalised to the reported value at the first frame.
//  - PowerSweep: the response was calibrated before from an illuminator power sweep (radiance
//    proportional to power; options.response_from_power_sweep) and is held; V and e estimated.
//  - Normalisation: no reported exposure; the first good frame has exposure 1 (relative units),
//    the back end holds the oldest keyframe of its window, and the gamma, which the data cannot
//    determine, is pinned only by the response basis and the prior towards the initial response,
//    or, with backend.gamma_gauge_weight > 0, pulled to a normalisation (photometric_backend.hpp;
//    off by default, as measured there); ambiguity_detail says which.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/image/frame.hpp"
#include "nirslam/photometric/exposure_estimator.hpp"
#include "nirslam/photometric/illumination_factor.hpp"
#include "nirslam/photometric/keyframe_selection.hpp"
#include "nirslam/photometric/photometric_backend.hpp"
#include "nirslam/photometric/photometric_tracker.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

// Given: response and vignette from files (given_calibration.hpp), held; the files fix gamma and scale.
enum class AmbiguityResolution { KnownExposures, PowerSweep, Normalisation, Given };
std::string_view to_string(AmbiguityResolution resolution);

struct PhotometricEstimate {  // immutable once published
  ResponseModel response;
  VignetteModel vignette;
  int model_version = 0;       // increments on each back-end update
  // The response is determined: some adopted update estimated it from exposure changes, without
  // the lamp's factor (under it the response is weakly determined, README "Illuminator
  // correction"), or it is held as given (files, a power sweep, backend.estimate_response off).
  // False while it is the initial guess or has only been fitted under the lamp's factor.
  bool response_determined = false;
  bool converged = false;
  int iterations = 0;
  double cost = 0.0;           // weighted Huber cost per observation
  double residual_rms = 0.0;   // grey levels, inliers
  int keyframes = 0;
  int points = 0;
  std::int64_t keyframes_dropped = 0;  // by the bounded queue, so far
  AmbiguityResolution ambiguity = AmbiguityResolution::Normalisation;
  std::string ambiguity_detail;  // e.g. "exposure times reported by the source"
  std::string status;            // human-readable convergence status / why nothing yet
  int estimates_rejected = 0;    // back-end estimates the gate kept from the frames so far (EstimateGate)
  double backend_ms = 0.0;       // wall time of the optimisation that produced this estimate
  double grey_low = 0.0;         // 1st / 99th percentile of the grey values the fit saw: the
  double grey_high = 0.0;        // response is extrapolated outside this range
  double radius_high = 0.0;      // 99th percentile of the samples' radius: V is continued beyond
  std::vector<std::pair<std::int64_t, double>> keyframe_exposures;  // frame index -> exposure (back end)
  // The lamp's beam exponent m when the halo factor is a held lens vignette times cos(alpha)^m
  // (PhotometricBackendOptions::beam_halo); std::nullopt otherwise.
  std::optional<double> beam_exponent;
  // ... and that lens vignette (flat with `calibration.lamp_halo: beam`). `vignette` is the sextic
  // closest to beam_lens cos(alpha)^m, which the back end fits; beam_lens cos(alpha)^m itself is
  // what the odometry's lamp factor applies, and it follows a steep beam further to the corners
  // (beam_halo.hpp).
  std::optional<VignetteModel> beam_lens;
};

struct ExposureSample {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  std::optional<double> estimated;  // front end, ms x gain (or relative)
  std::optional<double> reported;   // exposure_ms x gain from the source
  ExposureStatus status = ExposureStatus::NoEstimateYet;
};

struct CorrectedFrame {
  cv::Mat irradiance;              // CV_32FC1, G(I)/V on the 0..255 scale (the odometry's input)
  std::optional<double> exposure;  // estimated exposure of this frame (ms x gain, or relative)
  ExposureEstimate estimate;       // from ExposureEstimator
  double front_end_ms = 0.0;       // tracking + exposure + correction time
  bool keyframe = false;           // handed to the back end
  int model_version = 0;           // of the model that corrected this frame
};

// Which back-end estimates may reach the corrected frames and the exposure front end (issues 6
// and 8: a calibration whose model does not fit "leaves the last good estimate in place and says
// why"). The back end keeps iterating from its own state either way; only what is handed on is
// gated, so a later estimate that fits again gets through.
struct EstimateGate {
  // The back end's inlier residual (grey levels) above which the model is taken not to fit the
  // data: under a co-located lamp, calibration without the lamp factor sees the lamp's distance
  // change as radiance change and bends the response to absorb it, and its residual grows with
  // every keyframe (README "Illuminator correction"). 0: off.
  double max_residual_rms = 0.0;
  // Bounds on the inverse response's log-log slope, d log G / d log I, between grey levels 10 %
  // apart inside the range the fit saw (PhotometricEstimate::grey_low..grey_high, from grey 8
  // on): a camera's response is close to a power law there (gamma 1..3 for the curves the basis
  // is built on: slope 1..3), while a response that is flat over the observed values and jumps
  // at their top (slope 10 and more) explains any brightness change as nothing. 0: off.
  double max_response_slope = 0.0;
  double min_response_slope = 0.0;
};

// Why `response` with this fit's residual fails the gate, or an empty string when it passes.
std::string estimate_rejection(const EstimateGate& gate, const ResponseModel& response, double grey_low,
                               double grey_high, double residual_rms);

struct OnlineCalibrationOptions {
  PhotometricTrackerOptions tracker;
  // The exposure estimator's patches follow the surface (exposure_estimator.hpp): with the
  // estimates on the reported scale (exposure_scale.hpp), over three noise draws of the lamp-off
  // table the exposure median is under 2 % on 16 / 16 / 16 rows (means 0.69 / 0.61 / 0.61 %)
  // against 16 / 12 / 12 (0.98 / 1.32 / 1.18 %) with the fixed window. The illuminated mode keeps
  // the fixed window (PipelineOptions::lamp_mode_exposure_follows_surface).
  ExposureEstimatorOptions exposure{.follow_deformation = true};
  KeyframeSelectionOptions keyframes;
  PhotometricBackendOptions backend;  // holds the initial response and vignette
  bool background_thread = true;      // false: the back end runs inside process() (tests, batch)
  bool use_reported_exposures = true; // KnownExposures when the source reports them
  std::optional<ResponseModel> response_from_power_sweep;  // PowerSweep: held fixed
  int queue_capacity = 8;             // keyframes waiting for the back end
  int iterations_per_keyframe = 4;    // LM iterations per back-end update
  int final_iterations = 60;          // finish(): over every stored keyframe
  bool correct_images = true;         // compute CorrectedFrame::irradiance
  // The model the corrected frames use follows the estimate by at most this change of log G
  // (over the grey range the fit saw) and log V per frame. The odometry compares frames
  // corrected over its whole window (a second or more): a new estimate adopted at once (the
  // first one after the response becomes observable moves G by a factor of 20 at the dark end)
  // breaks brightness constancy there and tracking with it. 0: adopt every estimate at once.
  double max_correction_step_log = 0.01;
  bool run_backend = true;            // false: front end only, with the initial model held
  // The initial model is a calibration given from files (read_given_calibration), described by
  // this text (files and fit errors): held as it is, the back end off, every grey level trusted.
  // Empty: the initial model is only a start.
  std::string given_model;
  // Part of the initial model given from files and held (backend.estimate_response or
  // estimate_vignette off), described by this text; the rest is estimated. A held response names
  // the ambiguity resolution (Given) unless a power sweep does.
  std::string given_part;
  // Set: the corrected frames are divided by this vignette (the lens's alone) instead of the
  // estimated halo factor, whose beam the odometry's lamp factor then carries
  // (calibration.beam_in_odometry); the back end's energy still has the whole halo factor.
  std::optional<VignetteModel> correction_vignette;
  EstimateGate gate;                  // estimates that fail it are not handed on (see EstimateGate)
  // The grey range (0..255) the held initial response was fitted over (PhotometricEstimate::
  // grey_low / grey_high of the run that estimated it): the exposure estimator then trusts G
  // inside it and down-weights pixels outside (exposure_estimator.hpp). With the back end on,
  // each estimate's own range is used; without either (or with a power-sweep response, known
  // over all levels) every grey level is trusted.
  std::optional<std::pair<double, double>> initial_grey_range;
  // The back end's keyframe observations follow the surface (keyframe_selection.hpp), with the
  // tracks' deformation the tracker estimates (track_deformation.hpp; shared with the exposure
  // estimator's follow_deformation). On: over three noise draws of the lamp-off table, with the
  // back end's straight rim (vignette_rim_curvature_weight), better on response and vignette in
  // every draw. The pipeline's illuminated mode turns both off (PipelineOptions::lamp_mode_*):
  // there they cost the lamp mode's ATE (README "Photometric calibration accuracy").
  bool keyframes_follow_deformation = true;
  // Keyframes chosen on the reported exposure's change when the source reports one (and
  // use_reported_exposures), not on the front end's estimate (see online_calibration.cpp).
  bool keyframes_by_reported_exposure = true;
  // Fraction of full scale at or above which a keyframe sample counts as saturated (the back end's
  // one-sided constraint e V a L >= G(level), photometric_backend.hpp). Negative: full scale
  // (kFullScaleSaturationLevel) where the back end models what clipping does to the samples below it
  // (backend.clip_noise_grey > 0 with the predicted-grey residual, without the lamp's factor), else
  // the tracker's saturation_level. Only the true clip (full scale) says something about the
  // irradiance scale: at a level inside the observed range both sides of the bound scale with it.
  double keyframe_saturation_level = -1.0;
};

class OnlinePhotometricCalibration {
public:
  explicit OnlinePhotometricCalibration(OnlineCalibrationOptions options = {});
  ~OnlinePhotometricCalibration();  // joins the background thread
  OnlinePhotometricCalibration(const OnlinePhotometricCalibration&) = delete;
  OnlinePhotometricCalibration& operator=(const OnlinePhotometricCalibration&) = delete;

  // Front end on the caller's thread; keyframes go to the back end (never blocks on it).
  CorrectedFrame process(const Frame& frame);
  // The same under a co-located light whose distance to the tracked points the caller knows
  // (illumination_factor.hpp): the exposure estimate and the back end's energy carry the
  // (d_ref/d)^2 (P/P_ref) factor of every tracked point. Once frames come with it, keyframes
  // without it are left out of the back end's windows that have it.
  CorrectedFrame process(const Frame& frame, const FrameIllumination& illumination);
  // The latest estimate (never null; version 0 = the initial model), from any thread.
  std::shared_ptr<const PhotometricEstimate> estimate() const;
  // Per processed frame, caller's thread.
  const std::vector<ExposureSample>& exposure_history() const { return history_; }
  // The tracks of the last processed frame, caller's thread (valid until the next process()).
  const std::vector<TrackObservation>& last_tracks() const { return tracker_.last().tracks; }
  // Why the tracks of the frame before the last ended (photometric_tracker.hpp).
  const TrackEnds& last_track_ends() const { return tracker_.last().ended; }
  // The model the last corrected frame used (it follows estimate(), max_correction_step_log).
  const ResponseModel& correction_response() const { return correction_response_; }
  const VignetteModel& correction_vignette() const { return correction_vignette_; }
  std::int64_t keyframes_dropped() const;
  // Log illumination found later for tracked patches of an earlier frame (illumination_factor.hpp's
  // TrackIllumination): queued for the back end in order with the keyframes, and filled into that
  // frame's keyframe where it had none (PhotometricBackend::fill_unknown_illumination). Never blocks.
  void fill_unknown_illumination(std::int64_t frame_index, std::vector<TrackIllumination> values);
  // Observations filled that way so far (from any thread).
  std::int64_t illumination_filled() const;
  // A copy of the keyframes the back end holds, as it holds them (observations, their
  // log_illumination), once everything queued is processed: to see what the calibration was
  // given. Caller's thread; waits for the back end.
  std::vector<PhotometricKeyframe> stored_keyframes() const;
  // While held, the corrected frames keep the model they use now and do not follow new estimates
  // (the back end and the exposure front end go on). The caller's thread. The pipeline holds it
  // while the odometry initialises (PipelineOptions::hold_correction_frames): the initialiser
  // compares every frame with its first, and a correction that moves meanwhile is a brightness
  // change its affine model, held by the known exposures, cannot take up.
  void hold_correction(bool hold) { correction_held_ = hold; }
  bool correction_held() const { return correction_held_; }
  // While set, the corrected frames adopt every new estimate in full (no max_correction_step_log):
  // for frames nothing compares yet, as before the odometry starts. The caller's thread.
  void follow_at_once(bool at_once) { correction_at_once_ = at_once; }
  // The back end's model version the last corrected frame used in full: 0 for the initial model,
  // -1 while the correction is on its way between two models (max_correction_step_log).
  int correction_model_version() const { return correction_model_version_; }
  void reset();
  // Batch mode: waits for the back end to process everything queued, then runs a final full
  // optimisation over every stored keyframe and publishes it.
  void finish();

private:
  struct Job {
    enum Kind { Keyframe, Illumination, Finish, Reset } kind = Keyframe;
    PhotometricKeyframe keyframe;
    std::int64_t frame_index = 0;  // Illumination: the keyframe's frame
    std::vector<TrackIllumination> illumination;
  };
  void backend_loop();
  void run_job(Job& job);
  void publish(const BackendStep& step);
  void submit_and_wait(Job::Kind kind);
  std::shared_ptr<const PhotometricEstimate> initial_estimate() const;
  CorrectedFrame process_frame(const Frame& frame, const FrameIllumination* illumination);
  void correct(const Frame& frame, const TrackedFrame& tracked, cv::Mat& out);
  double keyframe_saturation_level(bool lamp_modelled) const;

  OnlineCalibrationOptions options_;

  // Caller's thread.
  PhotometricTracker tracker_;
  ExposureEstimator exposure_;
  KeyframeSelector selector_;
  std::vector<ExposureSample> history_;
  std::vector<double> log_illumination_;  // per track of the current frame
  int applied_version_ = 0;
  std::vector<float> inverse_lut_;   // G at 256 grey levels, of the correction model
  cv::Mat inverse_vignette_;         // 1 / V, for the current size and correction model
  int inverse_vignette_version_ = -1;
  // The model the frames are corrected with, moving towards the estimate (max_correction_step_log).
  ResponseModel correction_response_;
  VignetteModel correction_vignette_;
  int correction_version_ = -1;      // increments whenever the correction model moves
  bool correction_held_ = false;     // hold_correction()
  bool correction_at_once_ = false;  // follow_at_once()
  int correction_model_version_ = 0;
  void follow_estimate(const PhotometricEstimate& model);

  // Back-end thread (or the caller's when background_thread is false).
  PhotometricBackend backend_;
  int version_ = 0;
  bool saw_known_exposure_ = false;
  double last_backend_ms_ = 0.0;

  // Shared.
  mutable std::mutex queue_mutex_;
  mutable std::condition_variable queue_changed_;  // stored_keyframes() waits on it
  std::deque<Job> queue_;
  bool stopping_ = false;
  bool busy_ = false;
  std::int64_t dropped_ = 0;
  std::int64_t illumination_filled_ = 0;
  mutable std::mutex estimate_mutex_;  // guards only the pointer
  std::shared_ptr<const PhotometricEstimate> estimate_;
  std::thread thread_;
};

}  // namespace nirslam
