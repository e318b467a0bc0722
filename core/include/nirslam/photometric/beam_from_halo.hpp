#pragma once
// The lamp's beam out of the halo factor (issue 8): with the lamp on, the photometric calibration
// estimates H(x) = V(x) B(x), the lens vignetting times the beam pattern, because both are radial
// in the image. When V is known from an earlier calibration without the lamp (a DSO
// vignette.png), B = H / V; fitted by B = cos(alpha)^m, alpha the pixel's angle off the optical
// axis, it gives the beam exponent m the odometry's lamp factor and the lamp-offset estimator
// need (odometry.beam_exponent), and the beam's half angle, which a lamp's datasheet states.
// Both images may have any scale (vignette.png is scaled to its maximum): the fit has a constant.

#include <string>

#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"

namespace nirslam {

struct BeamFit {
  double beam_exponent = 0.0;  // m
  double half_angle_deg = 0.0; // where cos(alpha)^m = 1/2
  double log_scale = 0.0;      // the fit's constant: log(H / V) at the axis
  double rms_log = 0.0;        // of log(H / V) about the fit
  double max_alpha_deg = 0.0;  // the largest angle the samples reach
  int samples = 0;
  bool ok = false;
  std::string reason;          // why not, when not
};

// Fits m over every `step`-th pixel where both images are above `min_value` of their maximum.
// Throws std::invalid_argument when the images differ in size from each other or the camera.
BeamFit fit_beam_from_halo(const cv::Mat& halo, const cv::Mat& lens_vignette, const CameraModel& camera,
                           int step = 4, double min_value = 0.05);

// The other way round: H(x) = V(x) cos(alpha)^m, the halo factor of a lens vignette (CV_32FC1 of
// the camera's size, any scale) under a lamp of beam exponent m (its data sheet's half angle),
// CV_32FC1. Pixels whose ray the camera cannot unproject keep V.
cv::Mat halo_with_beam(const cv::Mat& lens_vignette, const CameraModel& camera, double beam_exponent);

// B(x) = H(x) / V(x) scaled to 1 at its maximum (CV_32FC1), for display and beam.png.
cv::Mat beam_pattern(const cv::Mat& halo, const cv::Mat& lens_vignette);

}  // namespace nirslam
