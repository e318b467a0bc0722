#pragma once
// What the UI and the headless writers see of the online photometric calibration: the current
// response and vignette, the exposure history, the convergence state and, when the source knows
// them (the simulator), the true curves. Published inside snapshots, shared between them until
// the estimate changes, never modified after publishing.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "nirslam/photometric/grey_range_advice.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

struct ExposurePoint {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  float estimated = 0.0f;        // ms x gain (or relative, see PhotometricView::exposure_unit); NaN when none
  float reference = 0.0f;        // as the source reported it (ms x gain), or its ground truth; NaN when unknown
  bool keyframe = false;         // handed to the back end
};

struct PhotometricView {
  bool enabled = false;          // the pipeline mode runs the calibration at all
  ResponseModel response;        // current estimate
  VignetteModel vignette;
  int model_version = 0;         // increments with every back-end update
  bool converged = false;
  int iterations = 0;
  double cost = 0.0;
  int keyframes = 0;
  int points = 0;
  std::string ambiguity;         // how gamma and scale were fixed, e.g. "known exposures: ..."
  std::string status;            // convergence status, or why there is no estimate yet
  std::string exposure_status;   // the last frame's exposure estimate: "estimated", or why not
  std::string exposure_unit = "ms";  // "ms" when anchored to reported exposures, else "relative"
  // The exposures' estimated values are on the reported scale (exposure_scale.hpp): the chain's
  // values times this factor, the median over this many frames (0: none reported, factor 1), as
  // times.txt has them.
  double exposure_scale = 1.0;
  int exposure_scale_frames = 0;
  // Where the data constrain the curves (PhotometricEstimate): the grey range of the back end's
  // samples and their largest radius; outside, the curves are continuations. 0 / 0 / 0: unknown.
  double grey_low = 0.0;
  double grey_high = 0.0;
  double radius_high = 0.0;
  // When the fitted response's samples stop short of the top: how far they reach and how much
  // brighter the images would have to be to measure the rest (grey_range_advice.hpp).
  std::optional<GreyRangeAdvice> range_advice;
  // The lamp's distance term (Illuminated mode): from how many odometry points the last frame's
  // distances came, or what it waits for; empty when the mode has no such term.
  std::string lamp_term;
  // The frames report the lamp on while this mode's calibration assumes constant radiance (the
  // calibrated mode): under a co-located lamp its estimate bends to explain the distance changes.
  bool lamp_not_modelled = false;
  // The lamp's offset from the camera centre as estimated (or why not), and its beam split from
  // the halo factor when the lens vignetting is known; empty when there is none.
  std::string lamp_offset;
  std::string lamp_beam;
  // Ground truth, when the source has it (simulator), for the overlays.
  std::optional<ResponseModel> true_response;
  std::optional<VignetteModel> true_vignette;
  // Under the co-located lamp: the lens vignetting times the lamp's beam, the truth of what the
  // vignette estimate then is (PhotometricTruth::halo).
  std::optional<VignetteModel> true_halo;
  std::vector<ExposurePoint> exposures;  // oldest first, bounded length
};

}  // namespace nirslam
