#pragma once

// Keyframe selection for the photometric back end (issue 6, after Bergmann et al., "Online
// photometric calibration of auto exposure video"). The back end fits the response, the vignette
// and the keyframes' exposures to the radiance of tracked points; a frame is worth adding when it
// sees the tracked points under a new exposure (response information), at new image positions
// (vignette information, via track turnover / motion), or when enough time has passed. Frames the
// front end could not use (black, saturated, too few tracks) are never keyframes.
//
// A keyframe keeps, per track, the grey values of kBackendPixels pixels of the tracked 9x9 patch
// (a 3 x 3 grid with a 3 px pitch) and their squared image gradient, for the gradient weight
// w = mu / (mu + |grad I|^2) of the paper's Eq. 2-5. Grey values are in 0..255 units (16-bit
// frames scaled), so G = f^-1 applies as a 256-level table does. A pixel that is not a normal
// sample is stored as a negative marker (so `grey < 0` means "not a normal sample" everywhere):
// kGreyDark at or below the black level, kGreySaturated at or above the saturation level (its
// irradiance is at least that of the saturation level: the back end's one-sided constraint,
// photometric_backend.hpp), kGreyMissing where the followed grid left the frame.
//
// The back end takes a track's k-th pixel in every keyframe for one surface point of constant
// radiance. With the fixed grid that is not so: as the camera approaches, the grid covers less of
// the surface around the tracked corner, whose surroundings differ from it, and the same darkening
// that made the exposure estimate drift (track_deformation.hpp) enters the fitted f and V. With
// `follow_surfaces` the grid follows the surface instead: pixel k is sampled (bilinearly, from
// the frame) at position + A o_k, A the track's deformation since its surface began
// (TrackObservation::deformation), and the gradient there; the observation keeps A and the surface
// number, and the back end takes each (track, surface) as its own points.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "nirslam/photometric/exposure_estimator.hpp"
#include "nirslam/photometric/photometric_tracker.hpp"

namespace nirslam {

inline constexpr int kBackendPixels = 9;
inline constexpr float kGreyDark = -1.0f;
inline constexpr float kGreySaturated = -2.0f;
inline constexpr float kGreyMissing = -3.0f;
inline constexpr int kBackendPixelPitch = 3;
// A saturation level at full scale itself: an 8-bit sample counts as saturated at 255 only (half a
// grey level of margin for interpolated values), so the normal samples reach 254
// (PhotometricBackendOptions::clip_noise_grey, which models what clipping does to them).
inline constexpr double kFullScaleSaturationLevel = 254.5 / 255.0;
// Offset (dx, dy) in pixels of back-end pixel k from the track position.
Eigen::Vector2d backend_pixel_offset(int k);

struct KeyframeObservation {
  std::int64_t track_id = 0;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // track centre, pixels
  std::array<float, kBackendPixels> grey{};            // 0..255, or a kGrey* marker (< 0)
  std::array<float, kBackendPixels> gradient_sq{};     // |grad I|^2, grey levels^2 per px^2
  // The grid's deformation (pixel k lies at position + A o_k) and the track's surface (see above);
  // I and 0 for the fixed grid.
  Eigen::Matrix2f deformation = Eigen::Matrix2f::Identity();
  std::int32_t surface = 0;
  // log(P / d^2) of the light at the track (illumination_factor.hpp); 0 without a light model
  // (every factor 1), NaN where the distance is unknown (the observation is left out).
  float log_illumination = 0.0f;
  // The image position of back-end pixel k.
  Eigen::Vector2d pixel(int k) const;
};

struct PhotometricKeyframe {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  int width = 0;
  int height = 0;
  double exposure = 1.0;          // the reported exposure x gain when known, else the front end's estimate
  bool exposure_known = false;    // reported by the source (and the back end is told to trust it)
  bool illumination_modelled = false;  // observations carry log_illumination (the light's factor)
  // The clip levels in grey levels: a kGreyDark sample was at most black_grey, a kGreySaturated
  // one at least saturation_grey.
  float black_grey = 0.03f * 255.0f;
  float saturation_grey = 0.97f * 255.0f;
  std::vector<KeyframeObservation> observations;
};

// The keyframe's back-end data from a tracked frame and its exposure estimate. `exposure` is what
// the keyframe starts with (reported or estimated). black_level / saturation_level: fractions of
// full scale beyond which a pixel counts as clipped. An observation is kept when at least one of its
// pixels is a normal sample or saturated.
// `log_illumination`, when given, holds each track's log(P / d^2) (aligned with tracked.tracks).
// `follow_surfaces`: the grid follows each track's deformation (see above; needs
// tracked.deformation_estimated and tracked.intensity).
PhotometricKeyframe make_photometric_keyframe(const TrackedFrame& tracked, double timestamp_s, double exposure,
                                              bool exposure_known, double black_level = 0.03,
                                              double saturation_level = 0.97,
                                              const std::vector<double>* log_illumination = nullptr,
                                              bool follow_surfaces = false);

struct KeyframeSelectionOptions {
  double min_interval_s = 0.05;             // at most 20 keyframes a second
  double max_interval_s = 1.0;              // a good frame becomes a keyframe at least this often
  double min_log_exposure_change = 0.04;    // |log(e / e_last keyframe)|: about 4 %
  double min_track_turnover = 0.25;         // fraction of the last keyframe's tracks gone or new
  double min_mean_motion_px = 20.0;         // mean shift of the shared tracks since the last keyframe
  int min_tracks = 20;                      // usable tracks for a keyframe
};

struct KeyframeDecision {
  bool keyframe = false;
  std::string reason;  // why (or why not)
};

class KeyframeSelector {
public:
  explicit KeyframeSelector(KeyframeSelectionOptions options = {}) : options_(options) {}

  // Decides on a frame after the front end processed it; a frame it accepts becomes the reference
  // of the next decisions.
  KeyframeDecision consider(const TrackedFrame& tracked, const ExposureEstimate& estimate, double timestamp_s);
  void reset() { last_.reset(); }
  const KeyframeSelectionOptions& options() const { return options_; }

private:
  struct Last {
    double timestamp_s = 0.0;
    double log_exposure = 0.0;
    std::vector<std::pair<std::int64_t, Eigen::Vector2d>> tracks;  // sorted by id
  };
  KeyframeSelectionOptions options_;
  std::optional<Last> last_;
};

}  // namespace nirslam
