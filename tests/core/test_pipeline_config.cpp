#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/config/pipeline_config.hpp"
#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/photometric/photometric_tracker.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

fs::path write_pipeline_yaml(const std::string& name, const std::string& text) {
  const fs::path file = fs::temp_directory_path() / ("nirslam_config_" + name + ".yaml");
  std::ofstream(file) << text;
  return file;
}

std::string pipeline_config_error(const fs::path& file) {
  try {
    load_pipeline_config(file);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(PipelineConfig, ShippedDefaultFileLoads) {
  const PipelineConfig config =
      load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/pipeline.yaml");
  EXPECT_EQ(config.worker.history_length, 600u);
  EXPECT_EQ(config.worker.pacing, Pacing::AsFastAsPossible);
  EXPECT_EQ(config.demo.width, 640);
  EXPECT_EQ(config.demo.frame_count, 900);
  EXPECT_DOUBLE_EQ(config.demo.illuminator_power_w, 50.0);
  // The mode follows the source's lamp; calibrated where it reports none.
  EXPECT_TRUE(config.worker.pipeline_mode_automatic);
  EXPECT_FALSE(config.worker.pipeline.lamp_cosine_to_calibration);
  EXPECT_TRUE(config.worker.pipeline.lamp_cosine_held_per_track);
  EXPECT_TRUE(config.worker.pipeline.light_distances.normal_from_inverse_depth_plane);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.track_light_cosines.min_cosine, TrackLightCosinesOptions{}.min_cosine);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.lamp_cosine_normal_radius_px, PipelineOptions{}.lamp_cosine_normal_radius_px);
  EXPECT_EQ(config.worker.pipeline.track_light_cosines.fits_before_hold, TrackLightCosinesOptions{}.fits_before_hold);
  EXPECT_EQ(config.worker.pipeline.mode, PipelineMode::Calibrated);
  EXPECT_EQ(config.worker.pipeline.odometry.window_size, 7);
  EXPECT_TRUE(config.worker.pipeline.calibration.background_thread);
  EXPECT_TRUE(config.worker.pipeline.calibration.run_backend);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.corrected_frame_exponent, 0.5);
  EXPECT_NEAR(config.worker.pipeline.raw_frame_exponent, 1.0 / 2.2, 1e-4);
  EXPECT_TRUE(config.worker.pipeline.odometry.lamp_factor_derivatives);
  EXPECT_FALSE(config.worker.pipeline.odometry.lamp_factor_derivatives_in_window);
  EXPECT_FALSE(config.worker.pipeline.lamp_factor_waits_for_response);
  EXPECT_TRUE(config.worker.pipeline.odometry.beam_corrected_weights);
  // The file spells the built-in keyframe weights out; they must stay the same numbers.
  EXPECT_NEAR(config.worker.pipeline.odometry.keyframe_translation_flow_weight,
              OdometryOptions{}.keyframe_translation_flow_weight, 1e-9);
  EXPECT_NEAR(config.worker.pipeline.odometry.keyframe_full_flow_weight, OdometryOptions{}.keyframe_full_flow_weight, 1e-9);
  EXPECT_EQ(config.worker.pipeline.calibration.tracker.skip_coarse_levels_at_border,
            PhotometricTrackerOptions{}.skip_coarse_levels_at_border);
  EXPECT_EQ(config.worker.pipeline.calibration.keyframes_follow_deformation,
            OnlineCalibrationOptions{}.keyframes_follow_deformation);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.vignette_rim_curvature_weight,
                   PhotometricBackendOptions{}.vignette_rim_curvature_weight);
  EXPECT_EQ(config.worker.pipeline.lamp_mode_keyframes_follow_surface, PipelineOptions{}.lamp_mode_keyframes_follow_surface);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.lamp_mode_vignette_rim_curvature_weight,
                   PipelineOptions{}.lamp_mode_vignette_rim_curvature_weight);
  EXPECT_EQ(config.worker.pipeline.lamp_mode_track_near_border, PipelineOptions{}.lamp_mode_track_near_border);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.tracker.min_reference_ncc, PhotometricTrackerOptions{}.min_reference_ncc);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.tracker.min_corner_isotropy, PhotometricTrackerOptions{}.min_corner_isotropy);
  EXPECT_EQ(config.worker.pipeline.calibration.tracker.align_reference_affine, PhotometricTrackerOptions{}.align_reference_affine);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.lamp_mode_min_reference_ncc, PipelineOptions{}.lamp_mode_min_reference_ncc);
  EXPECT_EQ(config.worker.pipeline.calibration.exposure.follow_deformation,
            OnlineCalibrationOptions{}.exposure.follow_deformation);
  EXPECT_TRUE(OnlineCalibrationOptions{}.exposure.follow_deformation);
  EXPECT_EQ(config.worker.pipeline.calibration.keyframes_by_reported_exposure,
            OnlineCalibrationOptions{}.keyframes_by_reported_exposure);
  EXPECT_EQ(config.worker.pipeline.lamp_mode_exposure_follows_surface, PipelineOptions{}.lamp_mode_exposure_follows_surface);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.residual_form, PhotometricBackendOptions{}.residual_form);
  EXPECT_EQ(PhotometricBackendOptions{}.residual_form, PhotometricResidualForm::PredictedGrey);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.lit_residual_form, PhotometricBackendOptions{}.lit_residual_form);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.point_rejection_sigmas, PhotometricBackendOptions{}.point_rejection_sigmas);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.lit_point_rejection_sigmas,
            PhotometricBackendOptions{}.lit_point_rejection_sigmas);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.rejection, PhotometricBackendOptions{}.rejection);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.reject_whole_track, PhotometricBackendOptions{}.reject_whole_track);
}

TEST(PipelineConfig, UnknownResidualFormNamesTheKeyAndTheValue) {
  const std::string error =
      pipeline_config_error(write_pipeline_yaml("residual_form", "calibration:\n  residual: grey\n"));
  EXPECT_NE(error.find("calibration.residual"), std::string::npos) << error;
  EXPECT_NE(error.find("'grey'"), std::string::npos) << error;
}

TEST(PipelineConfig, LampDistanceSourceIsReadAndAWrongOneNamed) {
  const PipelineConfig config = load_pipeline_config(write_pipeline_yaml(
      "lamp_distance_source", "pipeline:\n  lamp_distance_source: tracks-else-neighbours\n  lamp_track_min_parallax_deg: 2.5\n"));
  EXPECT_EQ(config.worker.pipeline.lamp_distance_source, LampDistanceSource::TracksElseNeighbours);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.track_light_distances.min_parallax_deg, 2.5);
  EXPECT_EQ(PipelineOptions{}.lamp_distance_source, LampDistanceSource::Neighbours);
  EXPECT_EQ(load_pipeline_config(write_pipeline_yaml("lamp_distance_source_held", "pipeline:\n  lamp_distance_source: held-neighbours\n"))
                .worker.pipeline.lamp_distance_source,
            LampDistanceSource::HeldNeighbours);
  EXPECT_EQ(load_pipeline_config(write_pipeline_yaml("lamp_distance_source_held_tracks", "pipeline:\n  lamp_distance_source: held-tracks\n"))
                .worker.pipeline.lamp_distance_source,
            LampDistanceSource::HeldTracks);
  const std::string error =
      pipeline_config_error(write_pipeline_yaml("lamp_distance_source_bad", "pipeline:\n  lamp_distance_source: depth\n"));
  EXPECT_NE(error.find("pipeline.lamp_distance_source"), std::string::npos) << error;
  EXPECT_NE(error.find("'depth'"), std::string::npos) << error;
}

TEST(PipelineConfig, LampDistanceBackfillNeedsTheTracksOwnPointAndAHeldNormal) {
  EXPECT_FALSE(PipelineOptions{}.lamp_distance_backfill);
  EXPECT_TRUE(load_pipeline_config(write_pipeline_yaml("lamp_distance_backfill",
                                                       "pipeline:\n  lamp_distance_source: held-tracks\n  lamp_distance_backfill: true\n"))
                  .worker.pipeline.lamp_distance_backfill);
  const std::string neighbours = pipeline_config_error(
      write_pipeline_yaml("lamp_distance_backfill_neighbours", "pipeline:\n  lamp_distance_backfill: true\n"));
  EXPECT_NE(neighbours.find("pipeline.lamp_distance_backfill"), std::string::npos) << neighbours;
  EXPECT_NE(neighbours.find("'neighbours'"), std::string::npos) << neighbours;
  EXPECT_TRUE(load_pipeline_config(write_pipeline_yaml("lamp_distance_backfill_cosine",
                                                       "pipeline:\n  lamp_distance_source: tracks\n  lamp_cosine_to_calibration: "
                                                       "true\n  lamp_distance_backfill: true\n"))
                  .worker.pipeline.lamp_distance_backfill);
  const std::string cosine = pipeline_config_error(write_pipeline_yaml(
      "lamp_distance_backfill_cosine_per_frame",
      "pipeline:\n  lamp_distance_source: tracks\n  lamp_cosine_to_calibration: true\n  lamp_cosine_held_per_track: false\n"
      "  lamp_distance_backfill: true\n"));
  EXPECT_NE(cosine.find("lamp_cosine_held_per_track"), std::string::npos) << cosine;
}

TEST(PipelineConfig, ResponseCurvatureWeightsWithAndWithoutTheLamp) {
  EXPECT_DOUBLE_EQ(PipelineOptions{}.calibration.backend.lit_log_curvature_weight, 100.0);
  const PipelineConfig config = load_pipeline_config(write_pipeline_yaml(
      "curvature", "calibration:\n  response_curvature_weight: 30\n  lamp_mode_response_curvature_weight: 3\n"));
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.log_curvature_weight, 30.0);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.lit_log_curvature_weight, 3.0);
  const std::string error =
      pipeline_config_error(write_pipeline_yaml("curvature_bad", "calibration:\n  lamp_mode_response_curvature_weight: -1\n"));
  EXPECT_NE(error.find("calibration.lamp_mode_response_curvature_weight"), std::string::npos) << error;
}

TEST(PipelineConfig, RepeatableBenchFileRunsTheBackEndInline) {
  const PipelineConfig config =
      load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-repeatable.yaml");
  EXPECT_FALSE(config.worker.pipeline.calibration.background_thread);
  EXPECT_EQ(config.worker.pipeline.mode, PipelineOptions{}.mode);
}

TEST(PipelineConfig, GivenCalibrationBenchFileAddsTheBeam) {
  const PipelineConfig config =
      load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-given-calibration.yaml");
  EXPECT_FALSE(config.worker.pipeline.calibration.background_thread);
  EXPECT_NEAR(config.worker.pipeline.odometry.beam_exponent, std::log(0.5) / std::log(std::cos(30.0 * M_PI / 180.0)), 0.01);
  EXPECT_FALSE(config.worker.pipeline.estimate_beam);
  // The same with the beam refined online from the data sheet's exponent (README's Table 2 with
  // the lens vignette of a lamp-off calibration).
  const PipelineConfig refined =
      load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-lens-vignette-beam-refined.yaml");
  EXPECT_FALSE(refined.worker.pipeline.calibration.background_thread);
  EXPECT_EQ(refined.worker.pipeline.given_calibration_holds, GivenCalibrationParts::Vignette);
  EXPECT_TRUE(refined.worker.pipeline.estimate_beam);
  EXPECT_TRUE(refined.worker.pipeline.beam_in_odometry);
  EXPECT_DOUBLE_EQ(refined.worker.pipeline.odometry.beam_exponent, config.worker.pipeline.odometry.beam_exponent);
  EXPECT_TRUE(refined.worker.pipeline.odometry.beam_corrected_weights);
  // Fully online: the halo factor the lamp's beam alone, no files.
  const PipelineConfig halo_beam = load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-lamp-halo-beam.yaml");
  EXPECT_FALSE(halo_beam.worker.pipeline.calibration.background_thread);
  EXPECT_EQ(halo_beam.worker.pipeline.lamp_halo, LampHaloModel::Beam);
  EXPECT_TRUE(halo_beam.worker.pipeline.given_calibration_folder.empty());
  EXPECT_TRUE(halo_beam.worker.pipeline.odometry.beam_corrected_weights);
  EXPECT_EQ(halo_beam.worker.pipeline.odometry.beam_exponent, 0.0) << "no data sheet";
  // The same with the lamp's distances and cosines from each patch's own track, back-filled.
  const PipelineConfig colit = load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-lamp-colit-calibration.yaml");
  EXPECT_FALSE(colit.worker.pipeline.calibration.background_thread);
  EXPECT_EQ(colit.worker.pipeline.lamp_halo, LampHaloModel::Beam);
  EXPECT_EQ(colit.worker.pipeline.lamp_distance_source, LampDistanceSource::HeldTracks);
  EXPECT_TRUE(colit.worker.pipeline.lamp_distance_backfill);
  EXPECT_TRUE(colit.worker.pipeline.lamp_cosine_to_calibration);
  EXPECT_TRUE(colit.worker.pipeline.lamp_cosine_held_per_track);
  EXPECT_DOUBLE_EQ(colit.worker.pipeline.calibration.tracker.min_corner_isotropy, 0.1);
  EXPECT_DOUBLE_EQ(colit.worker.pipeline.track_light_cosines.min_cosine, 0.35);
  EXPECT_DOUBLE_EQ(colit.worker.pipeline.lamp_cosine_normal_radius_px, 40.0);
  EXPECT_EQ(colit.worker.pipeline.track_light_cosines.fits_before_hold, 5);
  EXPECT_DOUBLE_EQ(colit.worker.pipeline.calibration.backend.lit_gradient_mu, 2.0);
  EXPECT_DOUBLE_EQ(colit.worker.pipeline.calibration.backend.gradient_mu, 0.25) << "lamp-off problems as by default";
  // The same with the response held from a sweep (the folder given on the command line).
  const PipelineConfig sweep = load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-lamp-sweep-response.yaml");
  EXPECT_EQ(sweep.worker.pipeline.given_calibration_holds, GivenCalibrationParts::Response);
  EXPECT_EQ(sweep.worker.pipeline.lamp_halo, LampHaloModel::Beam);
  EXPECT_TRUE(sweep.worker.pipeline.given_calibration_folder.empty());
  EXPECT_EQ(sweep.worker.pipeline.lamp_distance_source, colit.worker.pipeline.lamp_distance_source);
  EXPECT_EQ(sweep.worker.pipeline.lamp_distance_backfill, colit.worker.pipeline.lamp_distance_backfill);
  EXPECT_EQ(sweep.worker.pipeline.lamp_cosine_to_calibration, colit.worker.pipeline.lamp_cosine_to_calibration);
  EXPECT_DOUBLE_EQ(sweep.worker.pipeline.calibration.tracker.min_corner_isotropy, 0.1);
  EXPECT_DOUBLE_EQ(sweep.worker.pipeline.track_light_cosines.min_cosine, 0.35);
  EXPECT_DOUBLE_EQ(sweep.worker.pipeline.lamp_cosine_normal_radius_px, 40.0);
  EXPECT_EQ(sweep.worker.pipeline.track_light_cosines.fits_before_hold, 5);
  EXPECT_DOUBLE_EQ(sweep.worker.pipeline.calibration.backend.lit_gradient_mu, 2.0);
  // The lamp-off calibration that gives the lens vignette: repeatable, V straight at the rim.
  const PipelineConfig lens = load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/lens-calibration.yaml");
  EXPECT_FALSE(lens.worker.pipeline.calibration.background_thread);
  EXPECT_GT(lens.worker.pipeline.calibration.backend.vignette_rim_curvature_weight, 0.0);
}

TEST(PipelineConfig, LensVignetteBenchFileHoldsTheVignetteWithTheBeam) {
  const PipelineConfig config = load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/bench-lens-vignette.yaml");
  EXPECT_FALSE(config.worker.pipeline.calibration.background_thread);
  EXPECT_EQ(config.worker.pipeline.given_calibration_holds, GivenCalibrationParts::Vignette);
  EXPECT_NEAR(config.worker.pipeline.odometry.beam_exponent, std::log(0.5) / std::log(std::cos(30.0 * M_PI / 180.0)), 0.01);
}

TEST(PipelineConfig, PipelineSectionsSetModeAndStageOptions) {
  const PipelineConfig config = load_pipeline_config(write_pipeline_yaml(
      "stages", "pipeline:\n  mode: odometry\n  corrected_frame_exponent: 1.0\n  raw_frame_exponent: 0.5\n  lamp_distance_max_log_spread: 0.1\n"
                "  lamp_distance_plane_fit: false\n  lamp_cosine_to_calibration: true\n  lamp_cosine_held_per_track: false\n"
                "  lamp_cosine_min: 0.35\n  lamp_cosine_normal_radius_px: 40\n  lamp_cosine_fits_before_hold: 4\n"
                "  lamp_cosine_from_inverse_depth_plane: false\nodometry:\n  points_per_frame: 1500\n"
                "  window_size: 5\n  affine_a_prior_known_exposure: 2.5\n  surface_normal_fit: inverse-depth-plane\n"
                "calibration:\n  background_thread: false\n  iterations_per_keyframe: 2\n  estimate_model: false\n"
                "  track_near_border: true\n  align_first_patch: true\n  keyframes_follow_surface: false\n  vignette_rim_curvature_weight: 0.25\n"
                "  lamp_mode_keyframes_follow_surface: true\n  lamp_mode_vignette_rim_curvature_weight: 0.5\n"
                "  lamp_mode_track_near_border: false\n  exposure_follows_surface: false\n"
                "  lamp_mode_exposure_follows_surface: true\n  keyframes_by_reported_exposure: false\n"
                "  residual: observed\n  lamp_mode_residual: predicted\n"
                "  min_reference_ncc: 0.7\n  lamp_mode_min_reference_ncc: 0.9\n  min_corner_isotropy: 0.1\n"
                "  point_rejection_sigmas: 3.5\n  lamp_mode_point_rejection_sigmas: 2\n"
                "  point_rejection: against-its-patch\n  point_rejection_whole_tracks: true\n"
                "  lamp_mode_ambient: true\n  gradient_mu: 0.5\n  lamp_mode_gradient_mu: 2\n  beam_halo_exact: true\n"));
  EXPECT_EQ(config.worker.pipeline.mode, PipelineMode::Odometry);
  EXPECT_FALSE(config.worker.pipeline_mode_automatic) << "a named mode is not automatic";
  EXPECT_EQ(config.worker.pipeline.odometry.points_per_frame, 1500);
  EXPECT_EQ(config.worker.pipeline.odometry.window_size, 5);
  EXPECT_EQ(config.worker.pipeline.odometry.lamp_surface_normal_fit, SurfaceNormalFit::InverseDepthPlane);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.odometry.affine_a_prior_known_exposure, 2.5);
  EXPECT_FALSE(config.worker.pipeline.calibration.background_thread);
  EXPECT_EQ(config.worker.pipeline.calibration.iterations_per_keyframe, 2);
  EXPECT_FALSE(config.worker.pipeline.calibration.run_backend);
  EXPECT_TRUE(config.worker.pipeline.calibration.tracker.skip_coarse_levels_at_border);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.tracker.min_reference_ncc, 0.7);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.lamp_mode_min_reference_ncc, 0.9);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.tracker.min_corner_isotropy, 0.1);
  EXPECT_TRUE(config.worker.pipeline.calibration.tracker.align_reference_affine);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.point_rejection_sigmas, 3.5);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.lit_point_rejection_sigmas, 2.0);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.rejection, PhotometricBackendOptions::Rejection::AgainstItsPatch);
  EXPECT_TRUE(config.worker.pipeline.calibration.backend.reject_whole_track);
  EXPECT_TRUE(config.worker.pipeline.calibration.backend.lit_ambient);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.gradient_mu, 0.5);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.lit_gradient_mu, 2.0);
  EXPECT_TRUE(config.worker.pipeline.calibration.backend.beam_halo_exact);
  EXPECT_FALSE(PipelineOptions{}.calibration.backend.beam_halo_exact);
  EXPECT_FALSE(config.worker.pipeline.calibration.keyframes_follow_deformation);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.vignette_rim_curvature_weight, 0.25);
  EXPECT_TRUE(config.worker.pipeline.lamp_mode_keyframes_follow_surface);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.lamp_mode_vignette_rim_curvature_weight, 0.5);
  EXPECT_FALSE(config.worker.pipeline.lamp_mode_track_near_border);
  EXPECT_FALSE(config.worker.pipeline.calibration.exposure.follow_deformation);
  EXPECT_TRUE(config.worker.pipeline.lamp_mode_exposure_follows_surface);
  EXPECT_FALSE(config.worker.pipeline.calibration.keyframes_by_reported_exposure);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.residual_form, PhotometricResidualForm::ObservedInverse);
  EXPECT_EQ(config.worker.pipeline.calibration.backend.lit_residual_form, PhotometricResidualForm::PredictedGrey);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.corrected_frame_exponent, 1.0);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.raw_frame_exponent, 0.5);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.light_distances.max_log_spread, 0.1);
  EXPECT_FALSE(config.worker.pipeline.light_distances.fit_inverse_depth_plane);
  EXPECT_TRUE(config.worker.pipeline.lamp_cosine_to_calibration);
  EXPECT_FALSE(config.worker.pipeline.lamp_cosine_held_per_track);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.track_light_cosines.min_cosine, 0.35);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.lamp_cosine_normal_radius_px, 40.0);
  EXPECT_EQ(config.worker.pipeline.track_light_cosines.fits_before_hold, 4);
  EXPECT_FALSE(config.worker.pipeline.light_distances.normal_from_inverse_depth_plane);
}

TEST(PipelineConfig, LampOffsetConfiguredOrEstimated) {
  // The shipped file leaves the offset out: the illuminated mode estimates and reports it.
  const PipelineConfig shipped = load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/pipeline.yaml");
  EXPECT_FALSE(shipped.worker.pipeline.light_offset_configured);
  EXPECT_TRUE(shipped.worker.pipeline.estimate_light_offset);
  EXPECT_FALSE(shipped.worker.pipeline.apply_estimated_light_offset);
  EXPECT_EQ(shipped.worker.pipeline.odometry.init_geometric_frames, 20);
  EXPECT_TRUE(shipped.worker.pipeline.odometry.init_hold_geometric_pose);
  EXPECT_FALSE(load_pipeline_config(write_pipeline_yaml("hold_off", "odometry:\n  init_hold_geometric_pose: false\n"))
                   .worker.pipeline.odometry.init_hold_geometric_pose);
  EXPECT_EQ(load_pipeline_config(write_pipeline_yaml("geometric_off", "odometry:\n  init_geometric_frames: 0\n"))
                .worker.pipeline.odometry.init_geometric_frames,
            0);
  EXPECT_NE(pipeline_config_error(write_pipeline_yaml("geometric_bad", "odometry:\n  init_geometric_frames: 100\n"))
                .find("init_geometric_frames"),
            std::string::npos);
  const PipelineConfig config = load_pipeline_config(write_pipeline_yaml(
      "lamp", "odometry:\n  light_offset: [0.0, 0.02, 0.0]\n  apply_estimated_light_offset: true\n"
              "  lamp_factor_derivatives: false\n"
              "  lamp_factor_derivatives_in_window: true\n"
              "  beam_corrected_weights: false\n"
              "  lamp_in_traces: true\n"
              "calibration:\n  min_exposure_varying_fraction: 0.4\n"
              "pipeline:\n  lamp_factor_waits_for_response: true\n"));
  EXPECT_TRUE(config.worker.pipeline.odometry.lamp_in_traces);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.calibration.backend.min_exposure_varying_fraction, 0.4);
  EXPECT_FALSE(config.worker.pipeline.odometry.lamp_factor_derivatives);
  EXPECT_TRUE(config.worker.pipeline.odometry.lamp_factor_derivatives_in_window);
  EXPECT_TRUE(config.worker.pipeline.lamp_factor_waits_for_response);
  EXPECT_FALSE(config.worker.pipeline.odometry.beam_corrected_weights);
  EXPECT_TRUE(config.worker.pipeline.light_offset_configured);
  EXPECT_DOUBLE_EQ(config.worker.pipeline.odometry.light_offset.y(), 0.02);
  EXPECT_TRUE(config.worker.pipeline.apply_estimated_light_offset);
  // The lens vignette is found next to the config file; a missing one is named.
  std::ofstream(fs::temp_directory_path() / "nirslam_lens.png") << "x";
  const PipelineConfig lens = load_pipeline_config(write_pipeline_yaml("lens", "calibration:\n  lens_vignette: nirslam_lens.png\n"));
  EXPECT_EQ(lens.worker.pipeline.lens_vignette_file, fs::temp_directory_path() / "nirslam_lens.png");
  const std::string missing = pipeline_config_error(write_pipeline_yaml("lens_missing", "calibration:\n  lens_vignette: no_such_lens.png\n"));
  EXPECT_NE(missing.find("calibration.lens_vignette"), std::string::npos) << missing;
  EXPECT_NE(missing.find("no_such_lens.png"), std::string::npos) << missing;
  // So is a given photometric calibration's folder.
  fs::create_directories(fs::temp_directory_path() / "nirslam_given_calibration");
  const PipelineConfig given = load_pipeline_config(write_pipeline_yaml("given", "calibration:\n  given: nirslam_given_calibration\n"));
  EXPECT_EQ(given.worker.pipeline.given_calibration_folder, fs::temp_directory_path() / "nirslam_given_calibration");
  const std::string no_folder = pipeline_config_error(write_pipeline_yaml("given_missing", "calibration:\n  given: no_such_calibration\n"));
  EXPECT_NE(no_folder.find("calibration.given"), std::string::npos) << no_folder;
  EXPECT_NE(no_folder.find("no_such_calibration"), std::string::npos) << no_folder;
  // Which part of it is held.
  EXPECT_EQ(given.worker.pipeline.given_calibration_holds, GivenCalibrationParts::Both);
  const PipelineConfig lens_only = load_pipeline_config(
      write_pipeline_yaml("given_vignette", "calibration:\n  given: nirslam_given_calibration\n  given_holds: vignette\n"));
  EXPECT_EQ(lens_only.worker.pipeline.given_calibration_holds, GivenCalibrationParts::Vignette);
  EXPECT_FALSE(lens_only.worker.pipeline.estimate_beam);
  EXPECT_FALSE(lens_only.worker.pipeline.beam_in_odometry);
  const PipelineConfig beam = load_pipeline_config(write_pipeline_yaml(
      "given_beam", "calibration:\n  given: nirslam_given_calibration\n  given_holds: vignette\n  estimate_beam: true\n"
                    "  beam_in_odometry: true\n"));
  EXPECT_TRUE(beam.worker.pipeline.estimate_beam);
  EXPECT_TRUE(beam.worker.pipeline.beam_in_odometry);
  EXPECT_EQ(beam.worker.pipeline.lamp_halo, LampHaloModel::Polynomial);
  const PipelineConfig halo_beam =
      load_pipeline_config(write_pipeline_yaml("lamp_halo", "calibration:\n  lamp_halo: beam\n"));
  EXPECT_EQ(halo_beam.worker.pipeline.lamp_halo, LampHaloModel::Beam);
  const std::string bad_halo = pipeline_config_error(write_pipeline_yaml("lamp_halo_bad", "calibration:\n  lamp_halo: cosine\n"));
  EXPECT_NE(bad_halo.find("calibration.lamp_halo"), std::string::npos) << bad_halo;
  EXPECT_NE(bad_halo.find("'cosine'"), std::string::npos) << bad_halo;
  const std::string bad_part = pipeline_config_error(write_pipeline_yaml("given_lens", "calibration:\n  given_holds: lens\n"));
  EXPECT_NE(bad_part.find("calibration.given_holds"), std::string::npos) << bad_part;
  EXPECT_NE(bad_part.find("'lens'"), std::string::npos) << bad_part;
  const std::string bad_rejection =
      pipeline_config_error(write_pipeline_yaml("rejection_bad", "calibration:\n  point_rejection: track\n"));
  EXPECT_NE(bad_rejection.find("calibration.point_rejection"), std::string::npos) << bad_rejection;
  EXPECT_NE(bad_rejection.find("'track'"), std::string::npos) << bad_rejection;
}

TEST(PipelineConfig, MissingKeysKeepDefaults) {
  const PipelineConfig config = load_pipeline_config(write_pipeline_yaml("partial", "demo:\n  fps: 20\n"));
  EXPECT_DOUBLE_EQ(config.demo.fps, 20.0);
  EXPECT_EQ(config.demo.width, DemoOptions{}.width);
  EXPECT_EQ(config.worker.history_length, WorkerOptions{}.history_length);
}

TEST(PipelineConfig, ErrorsNameFileLineAndField) {
  const fs::path typo = write_pipeline_yaml("typo", "demo:\n  width: 640\n  hieght: 480\n");
  EXPECT_EQ(pipeline_config_error(typo), typo.string() + ":3: field 'demo.hieght': unknown key");

  const fs::path type = write_pipeline_yaml("type", "worker:\n  history_length: lots\n");
  EXPECT_NE(pipeline_config_error(type).find(":2: field 'worker.history_length': expected a number"), std::string::npos)
      << pipeline_config_error(type);

  const fs::path range = write_pipeline_yaml("range", "demo:\n  width: 10\n");
  EXPECT_NE(pipeline_config_error(range).find(":2: field 'demo.width': value 10 outside"), std::string::npos) << pipeline_config_error(range);

  const fs::path pacing = write_pipeline_yaml("pacing", "worker:\n  pacing: slow\n");
  EXPECT_NE(pipeline_config_error(pacing).find("field 'worker.pacing': expected 'fast' or 'recorded'"), std::string::npos);

  const fs::path section = write_pipeline_yaml("section", "mapping:\n  points: 2000\n");
  EXPECT_NE(pipeline_config_error(section).find(":1: field 'mapping': unknown section"), std::string::npos);

  const fs::path mode = write_pipeline_yaml("mode", "pipeline:\n  mode: dso\n");
  EXPECT_NE(pipeline_config_error(mode).find(":2: field 'pipeline.mode': expected 'auto', 'quality', 'odometry', 'calibrated', "
                                "'illuminated' or 'odometry-illuminated'"),
            std::string::npos)
      << pipeline_config_error(mode);

  const fs::path fit = write_pipeline_yaml("fit", "odometry:\n  surface_normal_fit: pca\n");
  EXPECT_NE(pipeline_config_error(fit).find(":2: field 'odometry.surface_normal_fit': expected 'spread' or 'inverse-depth-plane', got 'pca'"),
            std::string::npos)
      << pipeline_config_error(fit);

  const fs::path flag = write_pipeline_yaml("flag", "calibration:\n  background_thread: maybe\n");
  EXPECT_NE(pipeline_config_error(flag).find(":2: field 'calibration.background_thread': expected true or false"), std::string::npos)
      << pipeline_config_error(flag);

  const fs::path window = write_pipeline_yaml("window", "odometry:\n  window_size: 40\n");
  EXPECT_NE(pipeline_config_error(window).find("field 'odometry.window_size'"), std::string::npos) << pipeline_config_error(window);

  const fs::path broken = write_pipeline_yaml("broken", "demo: [1, 2\n");
  EXPECT_NE(pipeline_config_error(broken).find("not valid YAML"), std::string::npos) << pipeline_config_error(broken);

  EXPECT_NE(pipeline_config_error("/no/such/config.yaml").find("/no/such/config.yaml: cannot open"), std::string::npos);
}

}  // namespace
}  // namespace nirslam
