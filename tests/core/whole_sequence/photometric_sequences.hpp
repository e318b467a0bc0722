#pragma once

// The simulated sequences of the photometric calibration's accuracy table, shared by the table
// (test_photometric_accuracy.cpp) and the diagnostics that explain its rows
// (test_photometric_diagnostics.cpp), so that both run the same frames, env variants included.

#include <cstdlib>
#include <optional>
#include <string>

#include "nirslam/photometric/response_model.hpp"
#include "nirslam/sim/scene.hpp"
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

// A simulated frame's exposure as the back end takes it: the reported time times the gain.
inline double reported_exposure(const Frame& frame) { return *frame.exposure_ms * frame.gain.value_or(1.0); }

// The co-located 50 W lamp as the light (with the scene's faint ambient light).
inline SimulatorOptions co_lit(sim::SceneKind scene, ResponsePreset response, int frames) {
  SimulatorOptions o = calibration_sequence(scene, response, frames);
  o.powers_w = {50.0};
  // Diagnosis: the ambient light (the scene's own by default) does not fall off with the lamp's distance.
  if (const char* ambient = std::getenv("NIRSLAM_PHOTOMETRIC_COLIT_AMBIENT")) o.ambient_irradiance = std::atof(ambient);
  // Diagnosis: the beam's half angle (30 degrees by default; the halo factor V B is a sextic in r
  // within 0.0048 on average at 30, 0.0010 at 45 degrees).
  if (const char* half = std::getenv("NIRSLAM_PHOTOMETRIC_COLIT_BEAM_HALF_ANGLE")) o.beam_half_angle_deg = std::atof(half);
  // Diagnosis: the lamp's offset below the lens (5 cm by default), metres.
  if (const char* below = std::getenv("NIRSLAM_PHOTOMETRIC_COLIT_LAMP_BELOW")) o.light_offset_cam = Eigen::Vector3d(0.0, std::atof(below), 0.0);
  return o;
}

// The lamp's true incidence cos(theta) at the surface seen through `pixel` from the camera pose
// T_world_cam (a ray cast into the scene; its normal against the direction to the lamp);
// std::nullopt where the ray hits nothing.
inline std::optional<double> true_light_cosine(const Simulator& sim, const SE3& T_world_cam, const Eigen::Vector2d& pixel) {
  const auto ray = sim.camera()->unproject(pixel);
  if (!ray) return std::nullopt;
  const Eigen::Vector3d origin = T_world_cam.translation();
  const auto hit = sim::cast_ray(sim.scene(), origin, T_world_cam * ray->normalized() - origin);
  if (!hit) return std::nullopt;
  const Eigen::Vector3d light = T_world_cam * sim.options().light_offset_cam;
  return hit->normal.dot((light - hit->point).normalized());
}

}  // namespace nirslam::test_photometric
