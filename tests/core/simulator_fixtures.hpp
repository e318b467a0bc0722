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

// A bench scene under its lamp at a constant power, one ray a pixel (the bench renders 2x2), by
// default at half the bench's 640x480: short odometry runs.
inline SimulatorOptions lamp_sequence(sim::SceneKind scene, double power_w, std::int64_t frames, int width = 320,
                                      int height = 240) {
  SimulatorOptions o;
  o.scene = scene;
  o.powers_w = {power_w};
  o.frames = frames;
  o.width = width;
  o.height = height;
  o.supersampling = 1;
  return o;
}

}  // namespace nirslam::test_sequences
