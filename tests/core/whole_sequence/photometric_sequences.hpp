#pragma once

// The simulated sequences of the photometric calibration's accuracy table, shared by the table
// (test_photometric_accuracy.cpp) and the diagnostics that explain its rows
// (test_photometric_diagnostics.cpp), so that both run the same frames, env variants included.

#include <cstdlib>
#include <string>

#include "nirslam/photometric/response_model.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam::test_photometric {

// The calibration's test sequences: texture filtered independently of the viewing distance (a
// surface point's radiance does not change as the camera moves, see simulator.hpp); auto exposure
// from 2 ms, so the exposure ramps about 4x over the first ten frames and then settles.
// A wandering auto-exposure target (ae_target_swing, NIRSLAM_PHOTOMETRIC_SWING=0.3 or 0.7) keeps
// the exposure swinging 5-8x, but the response then comes out WORSE (room/log with known
// exposures: 19-24 grey levels off in the observed range, against 0.8 without the swing), and
// even a direct Debevec-Malik fit of the same keyframes lands there, so the observations
// themselves are biased when the exposure changes between most frames: not understood yet (the
// tracker's grey samples near clipped pixels, or tracking drift under brightness change, are
// candidates; PhotometricAccuracy.DiagnoseObservations separates those). Hence no swing here.
inline SimulatorOptions calibration_sequence(sim::SceneKind scene, ResponsePreset response, int frames) {
  SimulatorOptions o;
  o.scene = scene;
  o.width = 320;
  o.height = 240;
  o.supersampling = 1;
  o.frames = frames;
  o.texture_filtering = TextureFiltering::DistanceIndependent;
  o.exposure_mode = ExposureMode::Auto;
  o.exposure_ms = 2.0;
  o.ae_target_swing = 0.0;
  o.ae_target_period_frames = 50.0;
  o.response = ResponseModel::from_preset(response);
  // Variants for diagnosis (the README table uses the defaults above).
  if (const char* swing = std::getenv("NIRSLAM_PHOTOMETRIC_SWING")) o.ae_target_swing = std::atof(swing);
  // A brighter auto-exposure target (0.55 instead of 0.35 of full scale): the frames then reach
  // grey 205-255 (99th percentile) instead of 133-254 (PhotometricAccuracy.DiagnoseClipping), so
  // the data constrain G over most of the scale. Not the default: the table keeps today's rows.
  if (const char* target = std::getenv("NIRSLAM_PHOTOMETRIC_TARGET_GREY")) o.target_grey = std::atof(target);
  if (const char* texture = std::getenv("NIRSLAM_PHOTOMETRIC_TEXTURE"); texture && std::string(texture) == "pixel")
    o.texture_filtering = TextureFiltering::PixelFootprint;
  if (const char* footprint = std::getenv("NIRSLAM_PHOTOMETRIC_FOOTPRINT")) o.texture_footprint_m = std::atof(footprint);
  if (const char* samples = std::getenv("NIRSLAM_PHOTOMETRIC_SUPERSAMPLING")) o.supersampling = std::atoi(samples);
  // Another draw of the sensor noise: one table is one sample of basins the multi-start can land in.
  if (const char* seed = std::getenv("NIRSLAM_PHOTOMETRIC_SEED")) o.seed = static_cast<std::uint32_t>(std::strtoul(seed, nullptr, 10));
  return o;
}

inline SimulatorOptions constant_radiance(sim::SceneKind scene, ResponsePreset response, int frames) {
  SimulatorOptions o = calibration_sequence(scene, response, frames);
  o.powers_w = {0.0};   // illuminator off ...
  o.ambient_irradiance = 0.4;  // ... and an ambient light: radiance independent of the camera position
  return o;
}

}  // namespace nirslam::test_photometric
