#include "nirslam/config/pipeline_config.hpp"

#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "yaml_map_reader.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
using config_detail::load_yaml_file;
using config_detail::YamlMapReader;

PipelineConfig load_pipeline_config(const std::filesystem::path& file) {
  const YAML::Node root = load_yaml_file(file);
  PipelineConfig config;
  if (root.IsNull()) return config;  // an empty file keeps every default

  if (!root.IsMap()) throw InputError(file, root.Mark().line + 1, "expected sections 'worker' and 'demo'");
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    if (key != "worker" && key != "demo" && key != "pipeline" && key != "odometry" && key != "calibration")
      throw InputError(file, entry.first.Mark().line + 1, "field '" + key + "': unknown section");
  }

  YamlMapReader worker(root["worker"], file, "worker");
  worker.read<std::size_t>("history_length", config.worker.history_length, 2, 1'000'000);
  if (const auto pacing = worker.read_text("pacing")) {
    if (*pacing == "fast") config.worker.pacing = Pacing::AsFastAsPossible;
    else if (*pacing == "recorded") config.worker.pacing = Pacing::RecordedSpeed;
    else worker.fail_at("pacing", "expected 'fast' or 'recorded', got '" + *pacing + "'");
  }
  worker.reject_unknown_keys();

  PipelineOptions& pipeline = config.worker.pipeline;
  YamlMapReader stages(root["pipeline"], file, "pipeline");
  if (const auto mode = stages.read_text("mode")) {
    config.worker.pipeline_mode_automatic = *mode == "auto";
    if (const auto parsed = parse_pipeline_mode(*mode)) pipeline.mode = *parsed;
    else if (!config.worker.pipeline_mode_automatic)
      stages.fail_at("mode", "expected 'auto', 'quality', 'odometry', 'calibrated', 'illuminated' or 'odometry-illuminated', got '" +
                                 *mode + "'");
  }
  stages.read<std::size_t>("exposure_history", pipeline.exposure_history, 2, 1'000'000);
  stages.read<double>("corrected_frame_exponent", pipeline.corrected_frame_exponent, 0.1, 1.0);
  stages.read<double>("raw_frame_exponent", pipeline.raw_frame_exponent, 0.1, 1.0);
  // The lamp's distances handed to the calibration in 'illuminated' mode (light_distance_map.hpp).
  stages.read<double>("lamp_distance_max_log_spread", pipeline.light_distances.max_log_spread, 0.0, 10.0);
  stages.read_flag("lamp_distance_plane_fit", pipeline.light_distances.fit_inverse_depth_plane);
  stages.read_flag("lamp_cosine_to_calibration", pipeline.lamp_cosine_to_calibration);
  stages.read_flag("lamp_cosine_held_per_track", pipeline.lamp_cosine_held_per_track);
  stages.read<double>("lamp_cosine_min", pipeline.track_light_cosines.min_cosine, 0.0, 1.0);
  stages.read<double>("lamp_cosine_normal_radius_px", pipeline.lamp_cosine_normal_radius_px, 0.0, 200.0);
  stages.read<int>("lamp_cosine_fits_before_hold", pipeline.track_light_cosines.fits_before_hold, 1, 100);
  stages.read_flag("lamp_cosine_from_inverse_depth_plane", pipeline.light_distances.normal_from_inverse_depth_plane);
  if (const auto source = stages.read_text("lamp_distance_source")) {
    if (const auto parsed = lamp_distance_source_from_string(*source))
      pipeline.lamp_distance_source = *parsed;
    else
      stages.fail_at("lamp_distance_source", "expected 'neighbours', 'tracks', 'tracks-else-neighbours', 'held-neighbours' or 'held-tracks', got '" + *source + "'");
  }
  stages.read_flag("lamp_distance_backfill", pipeline.lamp_distance_backfill);
  if (const auto problem = lamp_distance_backfill_problem(pipeline)) stages.fail_at("lamp_distance_backfill", *problem);
  stages.read<double>("lamp_track_min_parallax_deg", pipeline.track_light_distances.min_parallax_deg, 0.1, 45.0);
  stages.read<double>("lamp_track_max_ray_error_px", pipeline.track_light_distances.max_ray_error_px, 0.05, 100.0);
  stages.read<int>("hold_correction_frames", pipeline.hold_correction_frames, -1, 100000);
  stages.read<int>("odometry_waits_for_model_frames", pipeline.odometry_waits_for_model_frames, 0, 100000);
  stages.read_flag("lamp_factor_waits_for_response", pipeline.lamp_factor_waits_for_response);
  stages.reject_unknown_keys();

  YamlMapReader odometry(root["odometry"], file, "odometry");
  odometry.read<int>("points_per_frame", pipeline.odometry.points_per_frame, 100, 20'000);
  odometry.read<int>("window_size", pipeline.odometry.window_size, 3, 12);
  odometry.read<int>("window_iterations", pipeline.odometry.window_iterations, 1, 50);
  odometry.read<double>("max_tracking_rms", pipeline.odometry.max_tracking_rms, 1.0, 255.0);
  odometry.read<int>("max_frames_between_keyframes", pipeline.odometry.max_frames_between_keyframes, 1, 1000);
  odometry.read<double>("keyframe_translation_flow_weight", pipeline.odometry.keyframe_translation_flow_weight, 0.0, 1e4);
  odometry.read<double>("keyframe_full_flow_weight", pipeline.odometry.keyframe_full_flow_weight, 0.0, 1e4);
  odometry.read<double>("affine_a_prior_known_exposure", pipeline.odometry.affine_a_prior_known_exposure, 0.0, 1e12);
  odometry.read<double>("affine_b_prior_known_exposure", pipeline.odometry.affine_b_prior_known_exposure, 0.0, 1e12);
  // The co-located lamp (used by the 'illuminated' and 'odometry-illuminated' modes).
  std::vector<double> offset;
  odometry.read_list<double>("light_offset", offset, -1e3, 1e3);
  if (odometry.has("light_offset")) {
    if (offset.size() != 3) odometry.fail_at("light_offset", "expected 3 numbers [x, y, z], got " + std::to_string(offset.size()));
    pipeline.odometry.light_offset = Eigen::Vector3d(offset[0], offset[1], offset[2]);
    pipeline.light_offset_configured = true;
  }
  odometry.read_flag("estimate_light_offset", pipeline.estimate_light_offset);
  odometry.read_flag("apply_estimated_light_offset", pipeline.apply_estimated_light_offset);
  odometry.read<double>("beam_exponent", pipeline.odometry.beam_exponent, 0.0, 100.0);
  odometry.read_flag("surface_normals", pipeline.odometry.lamp_surface_normals);
  if (const auto fit = odometry.read_text("surface_normal_fit")) {
    if (const auto parsed = surface_normal_fit_from_string(*fit)) pipeline.odometry.lamp_surface_normal_fit = *parsed;
    else
      odometry.fail_at("surface_normal_fit",
                       "expected 'spread' or 'inverse-depth-plane', got '" + *fit + "'");
  }
  odometry.read_flag("lamp_factor_derivatives", pipeline.odometry.lamp_factor_derivatives);
  odometry.read_flag("lamp_factor_derivatives_in_window", pipeline.odometry.lamp_factor_derivatives_in_window);
  odometry.read_flag("beam_corrected_weights", pipeline.odometry.beam_corrected_weights);
  odometry.read_flag("lamp_in_traces", pipeline.odometry.lamp_in_traces);
  odometry.read<int>("init_geometric_frames", pipeline.odometry.init_geometric_frames, 0, 60);
  odometry.read_flag("init_hold_geometric_pose", pipeline.odometry.init_hold_geometric_pose);
  odometry.reject_unknown_keys();

  YamlMapReader calibration(root["calibration"], file, "calibration");
  calibration.read_flag("background_thread", pipeline.calibration.background_thread);
  calibration.read_flag("use_reported_exposures", pipeline.calibration.use_reported_exposures);
  calibration.read_flag("estimate_model", pipeline.calibration.run_backend);
  // The response the back end starts from (and holds while it cannot estimate one): a preset's
  // name. The simulator's cameras default to the gamma preset too, so a benchmark that should not
  // start at the truth sets another one.
  if (const auto name = calibration.read_text("initial_response")) {
    if (const auto preset = parse_response_preset(*name))
      pipeline.calibration.backend.initial_response = ResponseModel::from_preset(*preset);
    else
      calibration.fail_at("initial_response", "expected linear, gamma, log or filmic, got '" + *name + "'");
  }
  calibration.read<int>("iterations_per_keyframe", pipeline.calibration.iterations_per_keyframe, 1, 100);
  calibration.read<int>("queue_capacity", pipeline.calibration.queue_capacity, 1, 1000);
  calibration.read<double>("min_exposure_varying_fraction", pipeline.calibration.backend.min_exposure_varying_fraction, 0.0, 1.0);
  calibration.read_flag("keyframes_follow_surface", pipeline.calibration.keyframes_follow_deformation);
  calibration.read_flag("exposure_follows_surface", pipeline.calibration.exposure.follow_deformation);
  calibration.read_flag("keyframes_by_reported_exposure", pipeline.calibration.keyframes_by_reported_exposure);
  calibration.read_flag("track_near_border", pipeline.calibration.tracker.skip_coarse_levels_at_border);
  calibration.read_flag("align_first_patch", pipeline.calibration.tracker.align_reference_affine);
  calibration.read<double>("vignette_rim_curvature_weight", pipeline.calibration.backend.vignette_rim_curvature_weight, 0.0, 1e6);
  // The keyframe samples' noise near full scale (photometric_backend.hpp, clip_noise_grey; 0: off).
  calibration.read<double>("clip_noise_grey", pipeline.calibration.backend.clip_noise_grey, 0.0, 50.0);
  // The straightness prior on log G above the observed grey range, without and with the lamp's
  // factor (photometric_backend.hpp, log_curvature_weight and lit_log_curvature_weight).
  calibration.read<double>("response_curvature_weight", pipeline.calibration.backend.log_curvature_weight, 0.0, 1e6);
  // Under the lamp's factor the response held as fitted without it (photometric_backend.hpp,
  // lit_holds_unlit_response).
  calibration.read_flag("lamp_mode_holds_response", pipeline.calibration.backend.lit_holds_unlit_response);
  calibration.read<double>("lamp_mode_response_curvature_weight", pipeline.calibration.backend.lit_log_curvature_weight, 0.0, 1e6);
  // The back end's residual form, without and with the lamp's factor (photometric_backend.hpp).
  for (const auto& [key, form] : {std::pair{"residual", &pipeline.calibration.backend.residual_form},
                                  std::pair{"lamp_mode_residual", &pipeline.calibration.backend.lit_residual_form}}) {
    if (const auto name = calibration.read_text(key)) {
      if (*name == "predicted")
        *form = PhotometricResidualForm::PredictedGrey;
      else if (*name == "observed")
        *form = PhotometricResidualForm::ObservedInverse;
      else
        calibration.fail_at(key, "expected predicted or observed, got '" + *name + "'");
    }
  }
  // Points the fitted model cannot explain left out after each solve (photometric_backend.hpp,
  // point_rejection_sigmas), without and with the lamp's factor; 0: off.
  calibration.read<double>("point_rejection_sigmas", pipeline.calibration.backend.point_rejection_sigmas, 0.0, 100.0);
  calibration.read<double>("lamp_mode_point_rejection_sigmas", pipeline.calibration.backend.lit_point_rejection_sigmas, 0.0, 100.0);
  if (const auto test = calibration.read_text("point_rejection")) {
    if (*test == "point")
      pipeline.calibration.backend.rejection = PhotometricBackendOptions::Rejection::Point;
    else if (*test == "against-its-patch")
      pipeline.calibration.backend.rejection = PhotometricBackendOptions::Rejection::AgainstItsPatch;
    else
      calibration.fail_at("point_rejection", "expected point or against-its-patch, got '" + *test + "'");
  }
  calibration.read_flag("point_rejection_whole_tracks", pipeline.calibration.backend.reject_whole_track);
  // The ambient light beside the lamp's (photometric_backend.hpp, lit_ambient).
  calibration.read_flag("lamp_mode_ambient", pipeline.calibration.backend.lit_ambient);
  // Eq. 2-5's mu, without and with the lamp's factor (photometric_backend.hpp, gradient_mu and
  // lit_gradient_mu); above zero, or every sample's weight would vanish.
  calibration.read<double>("gradient_mu", pipeline.calibration.backend.gradient_mu, 1e-6, 1e9);
  calibration.read<double>("lamp_mode_gradient_mu", pipeline.calibration.backend.lit_gradient_mu, 1e-6, 1e9);
  calibration.read_flag("lamp_mode_keyframes_follow_surface", pipeline.lamp_mode_keyframes_follow_surface);
  calibration.read<double>("lamp_mode_vignette_rim_curvature_weight", pipeline.lamp_mode_vignette_rim_curvature_weight, 0.0, 1e6);
  calibration.read_flag("lamp_mode_track_near_border", pipeline.lamp_mode_track_near_border);
  calibration.read<double>("min_reference_ncc", pipeline.calibration.tracker.min_reference_ncc, 0.0, 1.0);
  calibration.read<double>("min_corner_isotropy", pipeline.calibration.tracker.min_corner_isotropy, 0.0, 1.0);
  calibration.read<double>("lamp_mode_min_reference_ncc", pipeline.lamp_mode_min_reference_ncc, 0.0, 1.0);
  calibration.read_flag("lamp_mode_exposure_follows_surface", pipeline.lamp_mode_exposure_follows_surface);
  calibration.read<double>("max_residual_grey", pipeline.calibration.gate.max_residual_rms, 0.0, 255.0);
  calibration.read<double>("max_response_slope", pipeline.calibration.gate.max_response_slope, 0.0, 100.0);
  calibration.read<double>("min_response_slope", pipeline.calibration.gate.min_response_slope, 0.0, 100.0);
  if (const auto lens = calibration.read_text("lens_vignette")) {
    // Relative to the config file, so a rig's folder can carry its own calibration.
    std::filesystem::path lens_file(*lens);
    if (lens_file.is_relative()) lens_file = file.parent_path() / lens_file;
    if (!std::filesystem::exists(lens_file)) calibration.fail_at("lens_vignette", lens_file.string() + " does not exist");
    pipeline.lens_vignette_file = lens_file;
  }
  if (const auto given = calibration.read_text("given")) {
    std::filesystem::path folder(*given);
    if (folder.is_relative()) folder = file.parent_path() / folder;
    if (!std::filesystem::is_directory(folder))
      calibration.fail_at("given", folder.string() + " is not a folder (one holding pcalib.txt and vignette.png)");
    pipeline.given_calibration_folder = folder;
  }
  if (const auto holds = calibration.read_text("given_holds")) {
    const auto parts = given_calibration_parts_from_string(*holds);
    if (!parts) calibration.fail_at("given_holds", "expected both, response or vignette, got '" + *holds + "'");
    pipeline.given_calibration_holds = *parts;
  }
  calibration.read_flag("estimate_beam", pipeline.estimate_beam);
  calibration.read_flag("beam_in_odometry", pipeline.beam_in_odometry);
  calibration.read_flag("beam_halo_exact", pipeline.calibration.backend.beam_halo_exact);
  if (const auto halo = calibration.read_text("lamp_halo")) {
    const auto model = lamp_halo_model_from_string(*halo);
    if (!model) calibration.fail_at("lamp_halo", "expected polynomial or beam, got '" + *halo + "'");
    pipeline.lamp_halo = *model;
  }
  calibration.reject_unknown_keys();

  YamlMapReader demo(root["demo"], file, "demo");
  demo.read<int>("width", config.demo.width, 64, 8192);
  demo.read<int>("height", config.demo.height, 48, 8192);
  demo.read<std::int64_t>("frames", config.demo.frame_count, 0, 100'000'000);
  demo.read<double>("fps", config.demo.fps, 0.1, 1000.0);
  demo.read<double>("illuminator_power_w", config.demo.illuminator_power_w, 0.0, 150.0);
  demo.read<double>("exposure_ms", config.demo.exposure_ms, 0.001, 10'000.0);
  demo.read<std::uint32_t>("seed", config.demo.seed, 0, 0xffffffffu);
  demo.reject_unknown_keys();
  return config;
}

}  // namespace nirslam
