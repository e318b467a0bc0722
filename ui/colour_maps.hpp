#pragma once

#include <imgui.h>

namespace nirslam::ui {

// Colour scales for data, t in [0, 1] (clamped). Both are perceptually ordered, so a reader can
// tell "more" from "less" without the legend.
ImU32 time_colour(float t);   // blue -> cyan -> green -> yellow -> red (a turbo-like ramp)
ImU32 error_colour(float t);  // green (small) -> yellow -> red (large)
ImU32 heat_colour(float t);   // black -> purple -> orange -> pale yellow (for maps such as the vignette)

}  // namespace nirslam::ui
