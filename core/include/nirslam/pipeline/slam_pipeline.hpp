#pragma once
// The per-frame SLAM pipeline behind the worker, `run` and `bench` (DESIGN.md, "Data flow"):
//
//   Frame -> online photometric calibration (front end here, back end on its own thread)
//         -> corrected frame G(I)/V + exposure -> undistortion to a pinhole -> direct odometry
//
// and the immutable views of its state that snapshots carry to the UI. The mode chooses which
// stages run, so the same sequence can be compared with and without the calibration (the
// paper's Table 2 columns). Not thread-safe: one thread (the worker's) calls process().

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/camera/undistorter.hpp"
#include "nirslam/eval/alignment.hpp"
#include "nirslam/image/frame.hpp"
#include "nirslam/odometry/direct_odometry.hpp"
#include "nirslam/photometric/beam_from_halo.hpp"
#include "nirslam/photometric/exposure_scale.hpp"
#include "nirslam/photometric/given_calibration.hpp"
#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/pipeline/keyframe_light_backfill.hpp"
#include "nirslam/pipeline/keyframe_light_offset.hpp"
#include "nirslam/pipeline/light_distance_map.hpp"
#include "nirslam/pipeline/track_light_cosines.hpp"
#include "nirslam/pipeline/track_light_distances.hpp"
#include "nirslam/pipeline/track_light_points.hpp"
#include "nirslam/sources/source.hpp"
#include "nirslam/worker/photometric_view.hpp"
#include "nirslam/worker/trajectory_view.hpp"

namespace nirslam {

enum class PipelineMode {
  Quality,     // image quality only (entropy, clipping, features): no calibration, no odometry
  Odometry,    // plain direct odometry on the raw frames, affine brightness free (plain DSO)
  Calibrated,  // online photometric calibration, odometry on G(I)/V with the estimated exposures
  Illuminated,  // Calibrated + the co-located lamp's distance and power factor in the odometry
  // Odometry + the lamp's factor, without calibration: the correction's own effect on raw frames
  // (not in the bench order: the response is not linearised, so the factor is approximate).
  OdometryIlluminated,
};
std::string_view to_string(PipelineMode mode);
// "quality", "odometry", "calibrated", "illuminated", "odometry-illuminated"; std::nullopt for
// anything else.
std::optional<PipelineMode> parse_pipeline_mode(std::string_view name);
// Every mode, in the order above (for mode pickers).
std::vector<PipelineMode> pipeline_modes();
// The modes in the order `bench` compares them (each adds one stage to the one before): the
// paper's Table 2 columns odometry, calibrated, illuminated.
std::vector<PipelineMode> odometry_modes();
// What a mode runs.
bool runs_calibration(PipelineMode mode);
bool corrects_illuminator(PipelineMode mode);

// calibration.lamp_halo (PipelineOptions::lamp_halo).
enum class LampHaloModel { Polynomial, Beam };
std::optional<LampHaloModel> lamp_halo_model_from_string(const std::string& text);

enum class LampDistanceSource { Neighbours, Tracks, TracksElseNeighbours, HeldNeighbours, HeldTracks };
std::string_view to_string(LampDistanceSource source);
// "neighbours", "tracks", "tracks-else-neighbours", "held-neighbours", "held-tracks"; std::nullopt for
// anything else.
std::optional<LampDistanceSource> lamp_distance_source_from_string(std::string_view text);

struct PipelineOptions {
  PipelineMode mode = PipelineMode::Calibrated;
  OdometryOptions odometry;
  OnlineCalibrationOptions calibration;
  std::size_t exposure_history = 600;  // frames in the photometric view's exposure plot
  // The odometry sees corrected frames as 255 (G(I) / (255 V))^gamma with this gamma, and the
  // exposures and lamp factor raised to it (OdometryOptions::brightness_exponent). Linear
  // irradiance (1, as DSO takes G(I)/V) doubles, in log, every brightness change that is not
  // exposure, such as the co-located lamp's (d_h/d_t)^2, against the raw frames' gamma-encoded
  // grey (a camera's response is close to gamma 2.2); and its noise grows with brightness (shot
  // noise), while the odometry's Huber widths and pixel selection assume grey-level noise of one
  // size. The square root evens out shot noise. Measured with `bench` (README "Illuminator
  // correction"): linear input made the calibrated mode lose 0.1-4 m on 10 of 12 sequences.
  double corrected_frame_exponent = 0.5;
  // Raw frames (the modes without calibration) are taken as grey ~ irradiance^gamma with this
  // gamma, so the lamp's factor and power ratio reach them as g^gamma: a camera's response is
  // close to gamma 2.2 (the simulator's default curve is), and without calibration nothing better
  // is known. At 1 (linear, as before) the factor was 2.2 times too strong in log: the
  // 'odometry-illuminated' mode went from 0.11 / 0.15 / 0.013 m to 1.04 / 1.34 / 0.95 m on the
  // room at 20 / 100 W and the tunnel at 100 W (README "Illuminator correction"). The plain
  // 'odometry' mode uses neither, so this does not change it.
  double raw_frame_exponent = 1.0 / 2.2;
  // The corrected frames keep their model (OnlinePhotometricCalibration::hold_correction) while
  // the odometry initialises and for this many frames after it starts tracking (after a loss
  // too): a new estimate adopted then moves the correction (max_correction_step_log per frame)
  // under the initialiser and the first window, which compare frames over the whole time. On the
  // 20 W parking sequence in calibrated mode any estimate adopted in the first frames, even one
  // with G(128) = 61 for the true 56 (residual 1.2 grey levels), bent the rotation by 5 degrees
  // per 20 frames from frame 0 (ATE 3.3 m); held, 0.06 m (README "Illuminator correction").
  // -1: never held.
  int hold_correction_frames = 0;
  // With the calibration estimating its model online, the odometry starts at the first frame
  // corrected with a model the back end fitted (the correction follows every estimate at once
  // until then), or after this many frames without one (a camera whose exposure does not vary
  // may never give one); 0: at the first frame, on the initial model. The correction is then held
  // as above, so the initialiser and the first window compare frames corrected with a model fitted
  // to this camera, not with the initial guess: started on the initial model, the lamp mode of
  // Table 2 was at 0.0215 m when that guess was the simulator's own curve (gamma) and at 0.52 m
  // from a linear one (README "Illuminator correction", session 48).
  int odometry_waits_for_model_frames = 30;
  // Illuminated mode: the odometry's lamp factor waits for a determined response
  // (PhotometricEstimate::response_determined); until then the frames go to the odometry as in
  // Calibrated mode (OdometryFrame::lamp_factor_trusted), since the factor's brightness ratios
  // through the initial guess of the curve are wrong by its error's exponent. Off: from a linear
  // guess and frames 15 / 30 (24 runs, geometric mean ATE) it takes the lamp mode from 0.099 to
  // 0.030 m, but from the first frame with the simulator's own curve 0.0165 -> 0.0212 and from
  // frames 15 / 30 0.0180 -> 0.0313: with the halo factor as the lamp's beam the frames go without
  // the beam's correction until then, and a run that never fits the response never gets it
  // (README "Illuminator correction", session 50).
  bool lamp_factor_waits_for_response = false;
  // Illuminated mode: the calibration gets the lamp's distance to its tracked patches from the
  // odometry's points (light_distance_map.hpp), so its energy carries (d_ref/d)^2 (P/P_ref).
  // Off: the calibration assumes constant radiance, as in Calibrated mode (for comparisons).
  bool lamp_distances_to_calibration = true;
  // ... and cos(theta) from planes fitted to the points (patches where no plane fits are left out).
  // Off: it brings the tunnel's co-lit response from 37-38 to 5-12 grey levels and its halo factor
  // from 0.12-0.14 to 0.016-0.056, but the other scenes' halo factor goes 0.005-0.035 -> 0.014-0.034
  // and Table 2's lamp mode 0.0208 -> 0.0233 m (README "Illuminator correction", session 28).
  bool lamp_cosine_to_calibration = false;
  // That cosine with one normal per track, held from its first fit (track_light_cosines.hpp);
  // false: each frame's own fit (Table 2's lamp runs, co-lit response / halo factor: held 7.87 /
  // 0.025, each frame's 13.0 / 0.034; README "Illuminator correction", session 28).
  bool lamp_cosine_held_per_track = true;
  TrackLightCosinesOptions track_light_cosines;
  // The held normal's plane fitted to the odometry's points within this radius (pixels at 640
  // wide) instead of the distances' (light_distances.search_radius_px, 20): the inverse depth's
  // slope from points 10-20 % off in depth each is noisy over a few pixels, a normal tilted at
  // random makes the first frame's cosine too small on average, and the ratio the calibration
  // carries (cos_i / cos_ref = (h_i / h_ref) (d_ref / d_i), h the lamp's height over the
  // surface) then changes too much along the track. 0: the distances' radius.
  double lamp_cosine_normal_radius_px = 0.0;
  // The calibration's settings in that case (the illuminated mode with lamp distances), in place
  // of calibration.keyframes_follow_deformation and backend.vignette_rim_curvature_weight, which
  // hold for the other modes: following the surface with a straight rim is better without the
  // lamp model (three noise draws of the lamp-off table) and worse in the lamp mode (Table 2
  // 0.0260 -> 0.0292 m, halo factor 0.034 -> 0.069; README "Photometric calibration accuracy").
  // A rule of the mode, not of each keyframe: the mode's first keyframes come before the
  // odometry has distances.
  bool lamp_mode_keyframes_follow_surface = false;
  double lamp_mode_vignette_rim_curvature_weight = 0.0;
  // ... and of calibration.exposure.follow_deformation (the exposure estimator's patches following
  // the surface; on without the lamp's model, session 25): not measured with the lamp's factors.
  bool lamp_mode_exposure_follows_surface = false;
  // ... and of calibration.tracker.skip_coarse_levels_at_border (the calibration's tracks kept up
  // to the image border, where the lamp's halo factor falls steepest). Off: on, Table 2's lamp
  // mode went 0.0260 -> 0.0238 m but was better on 6 of 12 only (parking 20 W 0.71 -> 0.36 % of
  // the path, parking 50 / 100 W worse), and the co-lit calibration with the true distances and
  // cosine lost its vignette (room 0.0037 -> 0.044; README "Illuminator correction", session 24).
  bool lamp_mode_track_near_border = false;
  // ... and of calibration.tracker.min_reference_ncc (a track dropped once its patch correlates
  // with its first one below this; 0: no check). A patch over a depth edge takes one lamp distance
  // for pixels of two surfaces, the largest misfit found with the simulator's exact geometry
  // (README "Illuminator correction", session 29); the drift check drops many of them.
  double lamp_mode_min_reference_ncc = 0.0;
  // The cosine's normals (lamp_cosine_to_calibration) from the plane in inverse depth: the 3-D
  // scatter's were far off on the tunnel's walls (light_distance_map.hpp). Only the cosine asks
  // for a normal, so the distances are the same either way.
  LightDistanceMapOptions light_distances = [] {
    LightDistanceMapOptions o;
    o.normal_from_inverse_depth_plane = true;
    return o;
  }();
  // Where a tracked patch's lamp distance comes from: the odometry's points near it (Neighbours,
  // light_distance_map.hpp), the patch's own track triangulated from the odometry's poses
  // (Tracks, track_light_distances.hpp: none until its rays span the parallax), or the track
  // where it is triangulated and the neighbours elsewhere (TracksElseNeighbours), or the
  // neighbours' distance placed once per track as a surface point and carried with the poses
  // (HeldNeighbours, track_light_points.hpp), or that point placed at the track's first
  // triangulated distance instead, none before (HeldTracks: along the tracks the ratio was 2-4
  // times closer to the truth than the held neighbours' on the simulated street, parking and
  // tunnel, for a fifth of the observations; README "Illuminator correction", session 32).
  LampDistanceSource lamp_distance_source = LampDistanceSource::Neighbours;
  // With Tracks or HeldTracks: once a track has its point, the calibration's earlier keyframes
  // that had no distance for it take theirs from that point at the odometry's pose of their frame
  // (keyframe_light_backfill.hpp), so more observations get a ratio of the track's own point, not
  // only those after its triangulation. With lamp_cosine_to_calibration, their cosines from the
  // track's held normal (so it needs lamp_cosine_held_per_track).
  bool lamp_distance_backfill = false;
  TrackLightDistancesOptions track_light_distances;
  // The lamp's offset from the camera centre (Illuminated mode): when odometry.light_offset is
  // not configured, estimated at every keyframe from the recent keyframes (keyframe_light_offset.hpp)
  // and reported; used for the calibration's lamp distances only with apply_estimated_light_offset
  // (off until it is shown to help). beam_exponent < 0: the odometry's configured beam.
  // The lens vignetting alone (a vignette.png from a calibration with the lamp off): the
  // calibration's halo factor is then split into it and the lamp's beam (beam_from_halo.hpp),
  // shown, and the beam's exponent goes to the lamp-offset estimation when none is configured.
  std::filesystem::path lens_vignette_file;
  // A photometric calibration given as files (a folder with DSO's pcalib.txt and optionally
  // vignette.png: a TUM monoVO dataset's, or `nirslam calibrate`'s output), held in the modes
  // with calibration instead of estimating it online (given_calibration.hpp), as DSO runs with
  // those files. The vignette is then the lens's alone, so the odometry's beam term
  // (odometry.beam_exponent) stays on in the illuminated mode. Empty: estimated online.
  std::filesystem::path given_calibration_folder;
  // Which part of it is held; the other is estimated online (the back end on). A held response
  // leaves the halo factor (lens vignette and beam) to the back end, so the odometry's beam term
  // goes off as without files. A held vignette is the lens's: the halo held is
  // it times the configured beam, cos(alpha)^odometry.beam_exponent (beam_from_halo.hpp),
  // fitted to the vignette model, and the odometry's beam term goes off too (the corrected frames
  // no longer show the beam).
  GivenCalibrationParts given_calibration_holds = GivenCalibrationParts::Both;
  // With the lens vignette held (given_holds: vignette): the lamp's beam exponent m is estimated
  // online instead of taken from odometry.beam_exponent, the halo factor being the lens vignette
  // times cos(alpha)^m with m its only unknown (beam_halo.hpp). It starts from the configured
  // exponent, or from 2 (a 45-degree half-power half angle) when none is configured.
  bool estimate_beam = false;
  // With the lens vignette held in the illuminated mode: the frames are corrected with the lens
  // vignette alone and the odometry's lamp factor carries the beam, cos(alpha_h)^m /
  // cos(alpha_t)^m for each residual, with m configured or (estimate_beam) the back end's current
  // estimate handed on with every frame. Off: the corrected frames are divided by the whole halo
  // factor, so a changing m re-corrects new frames but not the window's keyframes.
  bool beam_in_odometry = false;
  // How the illuminated mode models the halo factor when no calibration is given: Polynomial,
  // the vignette model's v1..v3 with the lamp's beam in it (the paper's); Beam, the lamp's beam
  // cos(alpha)^m alone with m estimated online (from odometry.beam_exponent, or 2) and carried by
  // the odometry's lamp factor as with beam_in_odometry, the lens's own vignetting taken as flat,
  // so m absorbs it. No lamp-off sequence needed. Other modes: unaffected.
  LampHaloModel lamp_halo = LampHaloModel::Polynomial;
  bool light_offset_configured = false;
  bool estimate_light_offset = true;
  bool apply_estimated_light_offset = false;
  KeyframeLightOffsetOptions light_offset_estimation = beam_from_the_odometry();

  static KeyframeLightOffsetOptions beam_from_the_odometry() {
    KeyframeLightOffsetOptions o;
    o.beam_exponent = -1.0;
    return o;
  }
};

// Why `options` cannot run lamp_distance_backfill (it needs the track's own point, and with the
// cosine the track's held normal), or std::nullopt when they can. The config loader names the
// file and line with it; SlamPipeline's constructor refuses options built in code with it.
std::optional<std::string> lamp_distance_backfill_problem(const PipelineOptions& options);

struct PipelineTimings {
  double photometric_ms = 0.0;
  double undistort_ms = 0.0;
  double odometry_ms = 0.0;
  double mapping_ms = 0.0;  // of odometry_ms
};

struct PipelineFrameResult {
  cv::Mat corrected;                        // G(I)/V (CV_32FC1, 0..255), Calibrated mode only
  std::optional<CorrectedFrame> photometric;
  std::optional<OdometryResult> odometry;
  PipelineTimings timings;
  // Points the calibration's lamp distances came from (0: it ran without distances).
  std::size_t light_distance_points = 0;
};

class SlamPipeline {
public:
  // `camera` is the source's calibration (nullptr when it has none: the odometry is then off and
  // the trajectory view says why). `truth` the source's photometric ground truth, for overlays.
  SlamPipeline(PipelineOptions options, std::shared_ptr<const CameraModel> camera,
               std::optional<PhotometricTruth> truth = std::nullopt);
  ~SlamPipeline();
  SlamPipeline(const SlamPipeline&) = delete;
  SlamPipeline& operator=(const SlamPipeline&) = delete;

  // Throws std::invalid_argument for a frame the stages cannot take (size differs from the
  // camera's), naming the frame.
  PipelineFrameResult process(const Frame& frame);

  // Immutable views for snapshots; rebuilt only when something changed since the last call.
  std::shared_ptr<const PhotometricView> photometric_view();
  std::shared_ptr<const TrajectoryView> trajectory_view();

  // Batch mode: lets the calibration's back end finish its queue and run a final optimisation.
  void finish();

  const PipelineOptions& options() const { return options_; }
  PipelineMode mode() const { return options_.mode; }
  // nullptr when the mode does not run them (or there is no camera for the odometry).
  const DirectOdometry* odometry() const { return odometry_.get(); }
  const OnlinePhotometricCalibration* calibration() const { return calibration_.get(); }
  // The lamp distances the calibration got for the last frame (Illuminated mode; else nullptr).
  const LightDistanceMap* light_distances() const { return light_distances_.get(); }
  const TrackLightDistances* track_light_distances() const { return track_distances_.get(); }
  const TrackLightPoints* track_light_points() const { return track_points_.get(); }
  const TrackLightCosines* track_light_cosines() const { return track_cosines_.get(); }
  // The pose the last frame's lamp distances were computed for (constant velocity).
  const std::optional<SE3>& light_distance_pose() const { return predicted_T_world_cam_; }
  // The lamp offset estimated at the last keyframe (Illuminated mode, offset not configured).
  const std::optional<LightOffsetEstimate>& light_offset_estimate() const { return light_offset_estimate_; }
  // The offset the lamp distances use: configured, estimated and applied, or the camera centre.
  const Eigen::Vector3d& light_offset() const { return options_.odometry.light_offset; }
  // The pinhole the odometry works in (after undistortion), when it runs.
  const PinholeCamera* odometry_camera() const;
  // Why the odometry does not run, when it does not.
  const std::string& odometry_off_reason() const { return odometry_off_reason_; }

private:
  cv::Mat odometry_input(const Frame& frame, const cv::Mat& corrected);
  cv::Mat encode_irradiance(const cv::Mat& irradiance);
  void update_trajectory(const Frame& frame, const OdometryResult& result);
  std::shared_ptr<TrajectoryView> rebuild_trajectory_view();
  void project_active_points(TrajectoryView& view) const;
  PoseSample pose_sample(std::int64_t frame_index, double timestamp_s, int segment, const SE3& T_world_cam) const;
  // Builds the lamp distances for the frame about to be calibrated; false when there are none.
  bool predict_light_distances();
  void remember_odometry(const OdometryResult& result);
  // lamp_distance_backfill: the earlier keyframes' distances found this frame go to the
  // calibration, and a new keyframe's tracks without one start waiting.
  void backfill_lamp_distances(const Frame& frame, const FrameIllumination& illumination, bool keyframe);

  PipelineOptions options_;
  std::shared_ptr<const CameraModel> camera_;
  std::optional<PhotometricTruth> truth_;
  std::unique_ptr<Undistorter> undistorter_;  // null when the camera is already the pinhole
  std::unique_ptr<PinholeCamera> pinhole_;
  std::unique_ptr<OnlinePhotometricCalibration> calibration_;
  std::unique_ptr<DirectOdometry> odometry_;
  std::string odometry_off_reason_;

  // Lamp distances for the calibration (Illuminated mode).
  struct TrackedPose {
    std::int64_t frame_index = 0;
    int segment = 0;
    SE3 T_world_cam;
  };
  std::unique_ptr<LightDistanceMap> light_distances_;
  std::unique_ptr<LightDistanceMap> normal_map_;  // lamp_cosine_normal_radius_px's; null: light_distances_
  std::unique_ptr<TrackLightDistances> track_distances_;
  std::unique_ptr<TrackLightCosines> track_cosines_;
  std::unique_ptr<TrackLightPoints> track_points_;
  std::unique_ptr<KeyframeLightBackfill> backfill_;
  std::optional<SE3> predicted_T_world_cam_;  // of the frame about to be calibrated
  std::vector<Eigen::Vector3d> window_points_;  // the odometry's active points, world frame
  std::optional<TrackedPose> last_pose_;
  std::optional<TrackedPose> previous_pose_;
  std::size_t light_distance_points_ = 0;  // of the last frame
  std::optional<double> last_illuminator_power_w_;  // as the last frame reported it
  std::unique_ptr<KeyframeLightOffset> light_offset_;
  std::optional<LightOffsetEstimate> light_offset_estimate_;
  int light_offset_segment_ = -1;
  cv::Mat lens_vignette_;           // empty without a lens vignette file
  std::optional<BeamFit> beam_fit_;  // of the halo factor over it
  int beam_fit_version_ = -1;       // the model version it was fitted to
  int frames_tracking_ = 0;         // since the odometry last (re)started tracking (hold_correction_frames)
  bool lamp_factor_trusted_ = true;  // what the odometry's last frame said (lamp_factor_waits_for_response)
  bool odometry_started_ = false;   // it has had a frame (odometry_waits_for_model_frames)
  int frames_waiting_for_model_ = 0;
  bool odometry_waits_for_model() const;
  void fit_beam(const PhotometricEstimate& estimate);
  // Reads options_.given_calibration_folder into the calibration's options (the constructor's).
  void hold_given_calibration(double beam_exponent);
  // The halo factor as this lens vignette times the lamp's beam (held, or m estimated).
  void hold_lens_vignette(const VignetteModel& lens, double beam_exponent, bool estimate_beam);
  void estimate_light_offset(const OdometryFrame& input, const cv::Mat& irradiance, const OdometryResult& result);

  // View state.
  std::vector<ExposurePoint> exposures_;  // the chain's values; the view puts them on the reported scale
  ReportedExposureScaleTracker reported_exposure_scale_;
  std::shared_ptr<const PhotometricView> photometric_view_;
  bool photometric_dirty_ = true;
  std::unordered_map<std::int64_t, Eigen::Vector3d> truth_positions_;  // frame index -> true centre
  std::vector<Eigen::Vector3f> truth_path_;                           // in frame order
  std::optional<OdometryResult> last_odometry_;
  std::optional<Sim3Transform> alignment_;  // estimate -> ground truth, from the last rebuild
  std::vector<Eigen::Vector3d> active_points_;  // odometry world frame, from the last rebuild
  std::shared_ptr<const TrajectoryView> trajectory_view_;
  bool trajectory_rebuild_ = true;   // keyframe or status change: poses, points, alignment
  bool trajectory_dirty_ = true;
  cv::Mat float_buffer_;
  cv::Mat encoded_buffer_;
};

}  // namespace nirslam
