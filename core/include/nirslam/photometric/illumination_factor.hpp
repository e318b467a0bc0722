#pragma once

// The co-located illuminator in the photometric calibration (issue 8, calibration side). With the
// lamp beside the lens as the main light, the irradiance on a surface point p in frame i is
// J0 P_i B(alpha) cos(theta_i) / d_i^2, so the radiance the camera sees changes with the point's
// distance d_i to the light and the lamp's power P_i. The calibration's residual (Eq. 2-2) then
// carries the factor
//
//   a_i = (d_ref / d_i)^2 * (P_i / P_ref),   r_i^p = G(I_i^p) / (e_i V(r_i^p) a_i) - L_p,
//
// L_p now the point's radiance at the reference distance and power (its first usable
// observation). B(alpha) stays with the pixel (alpha is, for a light a few centimetres from the
// lens, the pixel's angle off the optical axis), so it is estimated as part of the halo factor
// H(x) = V(x) B(x) that the vignette polynomial models. cos(theta_i), the light's incidence on the
// surface, needs a surface normal: when the caller has one (FrameIllumination::light_cosine) the
// factor carries cos(theta_i) / cos(theta_ref) too, else it is left out (for a wall approached
// head-on it stays 1; for a floor seen ahead of a vehicle it does not).
//
// Factors are carried in the log domain: log a_i = log_illumination(P_i, d_i) - log_illumination
// (P_ref, d_ref), with log_illumination = log P - 2 log d, and NaN where a distance is unknown
// (such observations are left out, never guessed). Without any FrameIllumination every factor is
// 1, the constant-radiance model of issue 6.

#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>

#include <Eigen/Core>

namespace nirslam {

// What the caller knows about the light for one frame: the pipeline from the odometry's depths
// and pose, tests from the simulator's ground truth.
struct FrameIllumination {
  // Distance in metres from the illuminator to the surface seen at `pixel` (full-resolution pixel
  // coordinates of the frame); std::nullopt where unknown.
  std::function<std::optional<double>(const Eigen::Vector2d& pixel)> light_distance_m;
  // The same for a tracked patch by its track (TrackObservation::id), where the caller follows
  // the tracks themselves (the pipeline triangulates them from the odometry's poses). When set it
  // is asked first, and light_distance_m (if set) answers where it gives std::nullopt.
  std::function<std::optional<double>(std::int64_t track_id, const Eigen::Vector2d& pixel)> track_light_distance_m;
  // cos(theta) of the light's incidence on the surface seen at `pixel`. An empty function leaves
  // the cosine out everywhere; std::nullopt at a pixel leaves that observation out (a factor with
  // the cosine at one observation and without at another would be wrong).
  std::function<std::optional<double>(const Eigen::Vector2d& pixel)> light_cosine;
  // The same by track (the pipeline holds one normal per track); when set it replaces light_cosine.
  std::function<std::optional<double>(std::int64_t track_id, const Eigen::Vector2d& pixel)> track_light_cosine;
  // The lamp's power; std::nullopt: Frame::illuminator_power_w, and 1 when that is missing too
  // (lamp_power_w).
  std::optional<double> power_w;
};

// The power a frame's lamp factors take: the illumination's own, else the frame's
// (Frame::illuminator_power_w), else 1 (a lamp of unknown but constant power).
inline double lamp_power_w(const FrameIllumination& illumination, std::optional<double> frame_power_w) {
  return illumination.power_w.value_or(frame_power_w.value_or(1.0));
}

// A tracked patch's log_illumination found after its frame was calibrated: the pipeline learns a
// track's distance only once the track is triangulated, and then knows it for the track's earlier
// keyframes too (their poses are the odometry's), so the back end fills those observations in
// (PhotometricBackend::fill_unknown_illumination).
struct TrackIllumination {
  std::int64_t track_id = 0;
  double log_illumination = 0.0;
};

// log(P / d^2); NaN when the distance or power is not usable. With d_log_d, the derivative of the
// result with respect to d (-2 / d).
// With a cosine as well: log(P cos / d^2); NaN when the cosine is not a usable one.
inline double log_illumination(double power_w, std::optional<double> distance_m, std::optional<double> cosine);
inline double log_illumination(double power_w, std::optional<double> distance_m, double* d_log_d = nullptr) {
  if (!distance_m || !(*distance_m > 1e-3) || !std::isfinite(*distance_m) || !(power_w > 0.0) || !std::isfinite(power_w))
    return std::nan("");
  if (d_log_d != nullptr) *d_log_d = -2.0 / *distance_m;
  return std::log(power_w) - 2.0 * std::log(*distance_m);
}

inline double log_illumination(double power_w, std::optional<double> distance_m, std::optional<double> cosine) {
  if (!cosine || !(*cosine > 0.0) || !(*cosine <= 1.0)) return std::nan("");
  return log_illumination(power_w, distance_m) + std::log(*cosine);
}

}  // namespace nirslam
