#pragma once

// The power sweep an operator makes for the camera's response: the simulated rig on a tripod
// with its exposure locked, the wizard stepped through its powers (the worker and UI tests).

#include <chrono>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/sim/simulator.hpp"
#include "nirslam/worker/worker.hpp"

namespace nirslam::testing {

// The room at 160x120, the rig still, 4 ms: a sweep's frames differ only by the lamp.
inline SimulatorOptions still_rig() {
  SimulatorOptions sim;
  sim.scene = sim::SceneKind::Room;
  sim.motion = sim::MotionKind::Tripod;
  sim.width = 160;
  sim.height = 120;
  sim.supersampling = 1;
  sim.frames = 1000;
  sim.exposure_mode = ExposureMode::Fixed;
  sim.exposure_ms = 4.0;
  return sim;
}

// Starts a sweep over `powers` and confirms each power as the wizard asks for it, as the operator
// presses Capture; the worker must be running.
inline void sweep_through(Worker& worker, const std::vector<double>& powers, int frames_per_power) {
  using namespace std::chrono_literals;
  worker.post(command::Sweep{sweep_command::Start{powers, frames_per_power}});
  for (const double power : powers) {
    const auto asked = worker.wait_for(
        [&](const Snapshot& s) { return s.illumination && s.illumination->requested_power_w() == power; }, 20s);
    ASSERT_EQ(asked->illumination->requested_power_w(), power) << asked->message;
    worker.post(command::Sweep{sweep_command::Capture{power}});
  }
}

}  // namespace nirslam::testing
