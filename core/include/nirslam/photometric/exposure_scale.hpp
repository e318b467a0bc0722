#pragma once

// The estimated exposures on the scale the source reports. The front end's exposures are a chain
// of ratios (exposure_estimator.hpp) that takes its scale from its first good frame's reported
// exposure. Under auto exposure that frame is often the darkest of the exposure ramp, where a
// small error of G's shape at low grey levels is a large relative error, and every later frame
// inherits that one ratio's error: on the simulated constant-radiance table estimate / truth falls
// to 0.93 over the first ten frames (the ramp) and stays there, so every frame after is 7 % off
// while the exposures relative to each other are within 1-2 %. The scale is one number; taken
// from every frame with an estimate and a reported exposure (the median of log(reported /
// estimated)) instead of from the first, it carries the typical frame's error, not the first's,
// and the ratios between frames stay as estimated.
//
// Frames whose estimate restarted the chain or normalised it (status Restarted, FirstFrame) are
// left out of the median: their value is the reported one by construction. One factor for the
// whole history, also across restarts at a reported exposure (each restart sets the chain to
// that frame's reported value, so segments differ in scale by their own chain errors only).

#include <functional>
#include <queue>
#include <vector>

#include "nirslam/photometric/online_calibration.hpp"

namespace nirslam {

struct ReportedExposureScale {
  double factor = 1.0;  // multiplies every estimated exposure
  int frames = 0;       // frames the median was taken over (0: no reported exposures, factor 1)
};

// The running median over a growing history (two heaps: O(log n) a frame), for a live chain.
class ReportedExposureScaleTracker {
public:
  void add(const ExposureSample& sample);  // ignored unless it counts (see above)
  ReportedExposureScale current() const;
  void reset();

private:
  std::priority_queue<double> lower_;                                           // max-heap
  std::priority_queue<double, std::vector<double>, std::greater<double>> upper_;  // min-heap
};

// The same over a whole history (the tracker fed with every sample).
ReportedExposureScale reported_exposure_scale(const std::vector<ExposureSample>& history);

}  // namespace nirslam
