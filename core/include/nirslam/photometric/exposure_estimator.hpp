#pragma once

// Per-frame exposure from tracked patches (the real-time half of issue 6's online photometric
// calibration). Under constant scene radiance L, a pixel's irradiance G(I) / V(x) = e * L (G = f^-1
// in grey-level units, V the vignette), so for a patch seen in frames s and t
//
//   log_exposure_ratio = log( sum G(I_t)/V(x_t) ) - log( sum G(I_s)/V(x_s) ) = log(e_t / e_s)
//
// summed over the patch pixels unclipped in both frames. The patch is sampled at the tracked
// sub-pixel position in IRRADIANCE: G is applied to the four grey values before the bilinear
// weights. (Interpolating grey values first and applying G after biases a patch's irradiance by
// Jensen's inequality; on the simulator that was a 1.5 % exposure error after a 4x exposure ramp.) Each track is compared with its ANCHOR,
// the observation where it was first seen with a good exposure estimate, not with the previous
// frame: a chain of frame-to-frame ratios is a random walk, while anchors only add a step when a
// track is born. Every track gives a candidate log e_t = log e_anchor + log_exposure_ratio; the
// estimate is their Huber IRLS mean, started at the median with the MAD as scale, and tracks far
// off (occlusion, specular highlights, a drifted patch) are re-anchored at the new estimate.
//
// "Exposure" is what the image sees: exposure time x analogue gain. Normalisation: the first good
// frame gets exposure_ms x gain as the source reports them (gain 1 when not reported); when the
// source reports no exposure, the first good frame is 1 and the values are relative. When every
// anchored track is lost (a black frame in between), the chain restarts at the frame's reported
// exposure if there is one, else at the last estimate, and the status says so.
//
// Trusted grey range: the back end fits G only where its samples lie (BackendStep::grey_low ..
// grey_high, the 1st-99th percentile); outside, G is the basis's extrapolation, which the data do
// not constrain (photometric_backend.hpp: with no frame near saturation G is fixed only up to an
// irradiance scale inside the range, and may bend anywhere above it). A bright pixel read through
// the extrapolated part biases its track's ratio whenever its grey value changes between the
// anchor and now. Given the range (set_model's third argument), every pixel gets a weight
// w(I) = 1 inside it and exp(-d^2 / (2 width^2)) at d grey levels outside (floored at
// min_grey_weight, so no frame loses its estimate: a hard cut lost every estimate on two linear
// rows); a track's ratio is sum w G_t / sum w G_anchor with w the smaller of the pixel's two
// weights (the same weights on both sides, so the ratio stays unbiased where G is right), and the
// track's candidate enters the robust mean with its mean pixel weight.
//
// The same surface, not the same pixels (follow_deformation; off here by default since the
// estimator needs the tracker's deformation, on in the online calibration without the lamp's
// model, OnlineCalibrationOptions::exposure): a fixed
// 9 x 9 pixel window around a tracked point covers less and less of the surface as the camera
// approaches it, and the window's mean radiance changes with the track's magnification even where
// the radiance at the point itself is constant (track_deformation.hpp; on the simulated tunnel
// that is the exposure drift, estimate / truth 0.93 after 145 frames with the TRUE f and V). With
// follow_deformation a track's patch is sampled now at position + A_now A_anchor^-1 o (o the
// anchor's pixel offsets, A the track's deformation since its surface began, which the tracker
// estimates from the neighbouring tracks: TrackedFrame::deformation_estimated must be set). A
// track whose surface changed since its anchor (its neighbours no longer determined A) gives no
// candidate and is re-anchored at the frame's estimate. Measured: README "Photometric calibration
// accuracy" (with the TRUE f and V it removes the tunnel's drift; with the back end's own f and V
// it is judged together with the back end's observations following the surface,
// OnlineCalibrationOptions::keyframes_follow_deformation).
//
// Under a co-located light a track's radiance changes with its distance to the lamp and the
// lamp's power: given per-track factors (illumination_factor.hpp), the estimator removes that
// change before comparing with the anchor (see update()).

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nirslam/photometric/photometric_tracker.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

enum class ExposureStatus {
  Estimated,        // a new estimate from the tracks
  FirstFrame,       // set by the normalisation
  Restarted,        // no anchored track left: restarted (see `reason`)
  NoEstimateYet,    // no good frame seen yet
  BlackFrame,       // too many pixels at black: last estimate kept
  SaturatedFrame,   // too many pixels saturated: last estimate kept
  TooFewTracks,     // fewer usable tracks than min_tracks: last estimate kept
  NotFinite,        // the robust fit did not give a finite value: last estimate kept
};

struct ExposureEstimatorOptions {
  int min_tracks = 12;                 // usable tracks needed for an estimate
  int min_valid_pixels = kPatchPixels / 3;  // per track, unclipped in both observations
  double black_level = 0.03;           // samples at or below (fraction of full scale) are clipped
  double saturation_level = 0.97;      // samples at or above are clipped
  double max_black_fraction = 0.9;     // frame-level: beyond this the frame says nothing
  double max_saturated_fraction = 0.9;
  double huber_k = 1.345;              // in robust standard deviations
  double outlier_sigmas = 4.0;         // re-anchor tracks farther off than this
  double min_sigma = 1e-3;             // floor of the robust scale (log units)
  double trust_width_grey = 8.0;       // width of the weight's fall-off outside the trusted grey range
  double min_grey_weight = 1e-3;       // its floor
  // The patch follows the surface's local deformation since the anchor (see above; the tracker's
  // PhotometricTrackerOptions::estimate_deformation must be on); false: the fixed window at the
  // tracked position.
  bool follow_deformation = false;
};

struct ExposureEstimate {
  std::int64_t frame_index = 0;
  std::optional<double> exposure;      // ms x gain (or relative, see above); last good when kept
  double log_exposure_ratio = 0.0;     // log(e_t / e_{t-1}) of the estimates (0 when kept)
  double log_sigma = 0.0;              // robust spread of the track candidates (log units)
  int used_tracks = 0;
  int inlier_tracks = 0;
  ExposureStatus status = ExposureStatus::NoEstimateYet;
  std::string reason;
  bool updated() const {
    return status == ExposureStatus::Estimated || status == ExposureStatus::FirstFrame ||
           status == ExposureStatus::Restarted;
  }
};

class ExposureEstimator {
public:
  ExposureEstimator(const ResponseModel& response, const VignetteModel& vignette, ExposureEstimatorOptions options = {});

  // New response / vignette from the back end. Every anchor's patch is sampled again under the
  // new model from the grey values it keeps (a ratio with the old model on one end would be
  // biased), and the chain goes on with the anchors' exposures; a next frame with a reported
  // exposure restarts the chain there instead (status Restarted, the reason says so). Dropping
  // the anchors and restarting at the last estimate took the next frame's exposure change for
  // none, every few frames (as often as the back end updates), and left the chain to short
  // frame-to-frame steps.
  // `trusted_grey`: the grey range (0..255) the response was fitted over (see above); without it
  // every grey level has weight 1.
  void set_model(const ResponseModel& response, const VignetteModel& vignette,
                 std::optional<std::pair<double, double>> trusted_grey = std::nullopt);

  const ExposureEstimate& update(const TrackedFrame& tracked);
  // With a co-located light (illumination_factor.hpp): `log_illumination` holds each track's
  // log(P / d^2) in this frame (aligned with tracked.tracks, NaN where unknown). A track's
  // candidate is then log e_anchor + log ratio - (log a_t - log a_anchor): the part of its
  // brightness change that the light's distance and power explain is not taken for exposure.
  // Tracks without a factor at either end give no candidate. Switching between frames with and
  // without factors restarts the anchor chain (as a model change does).
  const ExposureEstimate& update(const TrackedFrame& tracked, const std::vector<double>* log_illumination);
  const ExposureEstimate& last() const { return last_; }
  void reset();

  // G(y) for y in fraction of full scale, in grey-level units (256-entry table, interpolated).
  double inverse_response(double y) const;
  // The weight of grey value y (fraction of full scale) under the trusted range (see above).
  double grey_weight(double y) const;

private:
  // The grey values a fixed-window patch is interpolated from: (kPatchSide + 1)^2 pixels from
  // the one left of and above the patch's first sample, and the patch's centre (for the
  // vignette's radius; the samples' shared sub-pixel fractions are its own).
  struct GreyWindow {
    Eigen::Matrix<float, (kPatchSide + 1) * (kPatchSide + 1), 1> grey =
        Eigen::Matrix<float, (kPatchSide + 1) * (kPatchSide + 1), 1>::Zero();
    Eigen::Vector2d position = Eigen::Vector2d::Zero();
  };
  struct Anchor {
    PatchSamples irradiance;  // G(I)/V, -1 where clipped
    PatchSamples weight;      // trust in G at each pixel's grey value (see above)
    GreyWindow grey;          // to sample irradiance and weight again under a new model
    double log_exposure = 0.0;
    double log_illumination = 0.0;  // log(P / d^2) when anchored (0 without a light model)
    Eigen::Matrix2d deformation_inverse = Eigen::Matrix2d::Identity();  // A_anchor^-1 (see above)
    std::int32_t surface = 0;           // the track's surface when anchored
  };
  // G(I)/V of one sample bilinear in irradiance from its four grey values c00 (left, above) ..
  // c11, with its trust; -1 and 0 where one of them is clipped.
  void irradiance_sample(float c00, float c01, float c10, float c11, double fx, double fy, double x, double y,
                         int cols, int rows, float& irradiance, float& weight) const;
  // The anchor's patch again under the current model, from its grey window.
  void resample(Anchor& anchor) const;
  // G(I)/V at the patch pixels position + A o (o the pixel offsets of the 9 x 9 grid), -1 where a
  // grey value is clipped; false when the patch does not fit in the image.
  bool irradiance_patch(const cv::Mat& intensity, const Eigen::Vector2d& position, const Eigen::Matrix2d& deformation,
                        PatchSamples& irradiance, PatchSamples& weight) const;
  // log of the ratio of the weighted patch irradiance sums over the pixels valid in both, and the
  // mean weight of those pixels; false when too few.
  bool log_irradiance_ratio(const PatchSamples& now, const PatchSamples& now_weight, const PatchSamples& anchor,
                            const PatchSamples& anchor_weight, double& log_ratio, double& trust) const;
  void anchor_all(const TrackedFrame& tracked, double log_exposure, bool only_new,
                  const std::vector<double>* log_illumination);
  const ExposureEstimate& keep(const TrackedFrame& tracked, ExposureStatus status, std::string reason);

  ExposureEstimatorOptions options_;
  std::vector<double> inverse_table_;  // G[i], grey-level units, i = 0..255
  std::vector<double> grey_weight_;    // w[i], i = 0..255 (all 1 without a trusted range)
  VignetteModel vignette_;
  std::unordered_map<std::int64_t, Anchor> anchors_;
  std::optional<double> log_exposure_;
  ExposureEstimate last_;
  std::vector<double> candidates_, residuals_, candidate_trust_;  // reused buffers
  std::vector<std::int64_t> candidate_ids_;
  std::vector<std::pair<double, double>> sorted_;  // (value, weight), for the weighted medians
  std::vector<PatchSamples> irradiance_, weight_;  // of tracked.tracks, this frame
  PatchSamples warped_irradiance_, warped_weight_;  // a patch sampled under its deformation
  std::vector<char> irradiance_valid_;
  bool model_changed_ = false;
  bool illumination_modelled_ = false;  // the last frame came with light factors
  int image_cols_ = 0, image_rows_ = 0;  // of the frames the anchors come from
};

}  // namespace nirslam
