#pragma once

#include <cstdint>
#include <memory>

#include "nirslam/sources/source.hpp"

namespace nirslam {

// The built-in sequence that `nirslam` shows when started without a dataset: a textured wall seen
// by a camera that drifts and turns in front of it, lit by a co-located NIR illuminator (bright
// centre, dark rim), with sensor noise. Deterministic for a given seed. It stands in until the
// ground-truth simulator exists; it carries no trajectory truth.
struct DemoOptions {
  int width = 640;
  int height = 480;
  std::int64_t frame_count = 300;  // frames before the end of the stream
  double fps = 30.0;
  double illuminator_power_w = 50.0;
  double exposure_ms = 10.0;
  std::uint32_t seed = 1;
};

std::unique_ptr<Source> make_demo_source(const DemoOptions& options = {});

}  // namespace nirslam
