#pragma once

// Simulated sequences shared by the photometric calibration's tests (core and worker suites).

#include <cstdint>

#include "nirslam/sim/simulator.hpp"

namespace nirslam::test_sequences {

// A small, fast room lit by ambient light only (no lamp): constant radiance, short fixed exposure,
// 240x180 without supersampling.
inline SimulatorOptions small_ambient_room(std::int64_t frames) {
  SimulatorOptions o;
  o.scene = sim::SceneKind::Room;
  o.width = 240;
  o.height = 180;
  o.supersampling = 1;
  o.frames = frames;
  o.exposure_ms = 2.0;
  o.powers_w = {0.0};
  o.ambient_irradiance = 0.4;
  return o;
}

}  // namespace nirslam::test_sequences
