#pragma once

#include <vector>

#include "nirslam/worker/snapshot.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// Photometric: what the online calibration currently believes, beside the truth when the source
// knows it (the simulator).
//   - status line: converged / optimising / waiting (with the reason), model version, keyframes
//     and points in the back end, how the gamma/scale ambiguity was resolved, and when the fitted
//     response's samples stop short of the top, how much brighter the images would have to be,
//   - the response f (normalised irradiance -> grey) and the inverse response G (grey -> irradiance,
//     the pcalib.txt table), the vignette V(r) as a radial plot and as a map over the image,
//   - the exposure of every frame over time (estimate, and reported or true value), keyframes marked.
// Curves are recomputed only when the estimate changes (model_version), not every UI frame.
class PhotometricPanel {
public:
  void draw(const Snapshot& snapshot);

  // Geometry of the last draw(), in screen pixels, for the screenshot tests (data areas).
  const ScreenRect& response_plot_rect() const { return response_plot_; }
  const ScreenRect& inverse_plot_rect() const { return inverse_plot_; }
  const ScreenRect& vignette_plot_rect() const { return vignette_plot_; }
  const ScreenRect& vignette_map_rect() const { return vignette_map_; }
  const ScreenRect& exposure_plot_rect() const { return exposure_plot_; }
  // The status row's advice when the response's samples stop short of the top (empty when none).
  const ScreenRect& range_advice_rect() const { return range_advice_; }

  static constexpr int kCurveSamples = 128;

private:
  void draw_status(const PhotometricView& view);
  void draw_curves(const PhotometricView& view, float height);
  void draw_vignette_map(const PhotometricView& view, ImVec2 size);
  void draw_exposure(const PhotometricView& view, float height);
  void update_curves(const PhotometricView& view);

  ScreenRect response_plot_;
  ScreenRect inverse_plot_;
  ScreenRect vignette_plot_;
  ScreenRect vignette_map_;
  ScreenRect exposure_plot_;
  ScreenRect range_advice_;
  // Cached curves of the estimate (and truth) that were last drawn.
  const PhotometricView* cached_for_ = nullptr;
  int cached_version_ = -1;
  std::vector<double> x_unit_, x_grey_;
  std::vector<double> response_, response_true_, inverse_, inverse_true_, vignette_, vignette_true_;
  // The measured grey range as irradiance (G of its ends), for the response plot's shading; 0 / 0
  // when unknown.
  double measured_irradiance_lo_ = 0.0, measured_irradiance_hi_ = 0.0;
  std::vector<double> frames_, exposure_, reference_;
  std::vector<double> reference_frames_;
};

}  // namespace nirslam::ui
