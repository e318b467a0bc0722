#pragma once

// What a photometric calibration writes (DESIGN.md, "Formats"): DSO / TUM monoVO files, so
// DSO-family tools can use what nirslam estimated, plus calibration.json with the model
// parameters; and the comparison with a simulated sequence's ground truth in the units the paper
// uses (DESIGN.md, "Measures that matter").
//
//   pcalib.txt        G(0..255), grey levels (write_pcalib)
//   vignette.png      V scaled to its maximum, 16-bit (write_vignette_png)
//   times.txt         "id timestamp_s exposure_ms": the ESTIMATED exposure of every frame that has
//                     one, in the input's frame ids (relative units under Normalisation)
//   calibration.json  response and vignette coefficients, ambiguity resolution and detail,
//                     convergence, per-frame exposures (estimated and reported), errors if known,
//                     and under a lamp modelled as lens times beam the beam's exponent and lens

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

struct PhotometricGroundTruth {
  ResponseModel response;
  VignetteModel vignette;
  std::vector<std::pair<std::int64_t, double>> exposures;  // frame index -> exposure_ms x gain
};

// From a folder written by `nirslam simulate` (groundtruth.json, frames.csv). std::nullopt when
// the folder has no groundtruth.json; InputError naming the file when it is malformed.
std::optional<PhotometricGroundTruth> read_simulated_ground_truth(const std::filesystem::path& folder);

struct PhotometricErrors {
  double response_mean_grey = 0.0;  // |G_est - G_true| over the 256 levels, grey levels
  double response_max_grey = 0.0;
  double vignette_mean = 0.0;       // |V_est - V_true| of both scaled to their maximum, over the image
  double vignette_max = 0.0;
  double exposure_mean_ms = 0.0;    // |e_est - e_true| with e_est scaled as compare_with_ground_truth says
  double exposure_max_ms = 0.0;
  double exposure_median_relative = 0.0;  // median |e_est / e_true - 1|
  double exposure_max_relative = 0.0;     // max |e_est / e_true - 1| (where the median hides a ramp)
  // The same after the one scale that best fits the whole sequence (the median of log(e_true /
  // e_est)) instead of the first frame's: the error of the exposures relative to each other.
  double exposure_median_relative_aligned = 0.0;
  int exposure_frames = 0;
};

// Errors of an estimate against ground truth. Exposures are compared on the reported scale when
// the samples carry reported exposures (exposure_scale.hpp, as times.txt has them), else scaled to
// the truth at the first frame that has an estimate and a true value (the Normalisation ambiguity).
PhotometricErrors compare_with_ground_truth(const ResponseModel& response, const VignetteModel& vignette,
                                            const std::vector<ExposureSample>& exposures,
                                            const PhotometricGroundTruth& truth, int width, int height);

struct CalibrationOutputInfo {
  std::string source;          // what was calibrated
  int width = 0;
  int height = 0;
  std::int64_t frames = 0;
  double wall_time_s = 0.0;
  double mean_front_end_ms = 0.0;
};

// Writes pcalib.txt, vignette.png, times.txt and calibration.json into `folder` (created).
// Throws std::runtime_error naming the file when a write fails.
void write_calibration_output(const std::filesystem::path& folder, const PhotometricEstimate& estimate,
                              const std::vector<ExposureSample>& exposures, const CalibrationOutputInfo& info,
                              const std::optional<PhotometricErrors>& errors);

}  // namespace nirslam
