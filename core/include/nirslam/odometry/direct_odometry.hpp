#pragma once

// Direct sparse monocular odometry in the class of DSO (Engel, Koltun, Cremers 2018):
// coarse-to-fine direct alignment of every frame to the newest keyframe, immature points whose
// inverse depth is found by epipolar search, and a sliding window of keyframes optimised jointly
// (poses, affine brightness, inverse depths) with old keyframes marginalised into a prior.
//
// Brightness model between a host keyframe h and a target frame t (per frame affine a, b and,
// when known, the exposure e):  I_t(x') = exp(a_t - a_h) (e_t / e_h) (I_h(x) - b_h) + b_t.
// Without an exposure e = 1 and a, b are nearly free (plain DSO); with one, a strong prior keeps
// a and b near 0, so the exposure ratio carries the brightness change.
//
// Scale is monocular and arbitrary (the initialiser sets the mean inverse depth of its points to
// 1). process() is not thread-safe: call it from one thread.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/geometry/se3.hpp"
#include "nirslam/odometry/surface_normal_fit.hpp"

namespace nirslam {

struct OdometryOptions {
  // Image pyramid: levels used by the coarse tracker and initialiser (the coarsest level is at
  // least min_coarsest_width pixels wide; fewer levels are used for small images).
  int pyramid_levels = 5;
  int min_coarsest_width = 40;

  // Points.
  int points_per_frame = 2000;          // active points kept in the window
  int immature_points_per_keyframe = 1500;
  double min_gradient = 7.0;            // grey levels added to the region's median gradient
  int max_epipolar_search_px = 30;      // along the epipolar line, at level 0 (640x480)
  double min_trace_quality = 3.0;       // second-best / best energy along the line
  double max_activation_interval_px = 8.0;
  bool drop_points_out_of_newest = true;  // points the newest keyframe cannot see leave the window
  bool marginalise_points_out_of_view = true;  // ... into the prior (else they are just dropped)

  // Window.
  int window_size = 7;                  // keyframes
  int window_iterations = 6;            // Levenberg-Marquardt iterations per keyframe
  double huber_threshold = 9.0;         // grey levels
  double gradient_weight_c = 50.0;      // w = c^2 / (c^2 + |grad I|^2)
  double outlier_energy = 12.0 * 12.0;  // per pattern pixel: a residual above is an outlier

  // Keyframes: a new keyframe when the weighted sum of the rms optical flow (translation
  // alone, and translation + rotation, as a fraction of w + h) and the brightness change
  // exceeds 1, or when the tracking residual doubled since the keyframe's first frame. DSO's
  // weights: the full flow's is half the translation's, so turning alone makes keyframes half
  // as often (with the translation's weight every frame of the street's turns became a
  // keyframe: 1255 against 900 over the twelve bench sequences; README "Speed").
  double keyframe_translation_flow_weight = 0.04 * (640 + 480);  // DSO's setting_maxShiftWeightT
  double keyframe_full_flow_weight = 0.02 * (640 + 480);         // DSO's setting_maxShiftWeightRT
  double keyframe_brightness_weight = 2.0;                       // DSO's setting_maxAffineWeight
  int max_frames_between_keyframes = 30;

  // Tracking.
  int tracking_iterations_per_level = 8;
  double max_tracking_rms = 25.0;       // grey levels (Huber-weighted rms); above: lost
  double min_tracking_inlier_fraction = 0.3;

  // Brightness priors: energy weights pulling a and b of each keyframe to 0 (the first keyframe
  // of a segment is fixed). Without an exposure the prior is weak compared with the data (whose
  // Hessian in a is ~1e7-1e8 per keyframe pair) but keeps the brightness gauge from drifting;
  // the tracker uses a tenth of these. A frame lit by a lamp the odometry does not model
  // (illuminator_power_w > 0 without illuminator_correction) counts as without an exposure.
  double affine_a_prior_known_exposure = 1e10;
  double affine_b_prior_known_exposure = 1e6;
  double affine_a_prior_free = 1e5;
  double affine_b_prior_free = 1e2;
  // The images' grey values are proportional to irradiance^gamma (1: linear, DSO's G(I)/V; the
  // pipeline hands corrected frames on as their square root, PipelineOptions::
  // corrected_frame_exponent): a frame's exposure and lamp power enter the brightness ratio, and
  // the lamp's factor g the residual, raised to gamma.
  double brightness_exponent = 1.0;

  // The co-located illuminator (DESIGN.md, "The illuminator model"): with the correction on, the
  // residual between host h and target t carries g = (d_h / d_t)^2, d the distance from the lamp
  // to the point from the current depth and pose estimates (in tracking and in the window, with
  // its derivatives), and the frames' illuminator powers P multiply their exposures, so the
  // brightness ratio carries P_t / P_h (P = 1 when a frame does not say). The light sits at
  // `light_offset` in the camera frame, in the odometry's units (monocular: the initialiser
  // sets the mean inverse depth of its points to 1, so this is a fraction of the first scene
  // depth; 0 = at the camera centre).
  // A beam B(alpha) = cos(alpha)^m around the optical axis adds B(alpha_t) / B(alpha_h) to g;
  // m = 0 leaves the beam to the photometric calibration's halo factor (calibrated frames).
  bool illuminator_correction = false;
  Eigen::Vector3d light_offset = Eigen::Vector3d::Zero();
  double beam_exponent = 0.0;
  // cos(theta) of the lamp's light on the surface, from normals fitted to neighbouring points'
  // depths (odometry/surface_normals.hpp), where a plane fits.
  bool lamp_surface_normals = true;
  // How those normals are fitted (surface_normals.hpp).
  SurfaceNormalFit lamp_surface_normal_fit = SurfaceNormalFit::Spread;
  // g's derivatives in the Jacobians (false: g evaluated at the current estimates only).
  bool lamp_factor_derivatives = true;
  // ... in the window optimisation too, where they tie the points' depths to the brightness
  // model. Off, the window holds g at each linearisation's estimates and the frame-to-keyframe
  // tracking keeps them: an error in the estimated beam or response (the garage's glossy floor
  // raises m from 5.7 to 6.9) then no longer pulls the depths against the translation, the scale
  // drift of the fully online lamp mode (Table 2 from the first frame 0.0237 -> 0.0165 m; from
  // frames 15 and 30 0.0169 -> 0.0180 m, one street run; README "Illuminator correction",
  // session 49). Where the beam is right they help (IlluminatorWall tests).
  bool lamp_factor_derivatives_in_window = false;
  // With a beam: residuals and gradients divided by the target's B(alpha_t)^gamma before
  // weighting, as in frames corrected for the beam (LampGeometry::beam_corrected_weights).
  // Measured better with every calibration tried (README "Illuminator correction").
  bool beam_corrected_weights = true;
  // The lamp's factor also in the immature points' epipolar search (ImmaturePoint::trace), at
  // each candidate's inverse depth; else the search sees the lamp's brightening and beam as
  // brightness change the frame pair's affine transfer does not hold. Off: over the twelve a wash
  // (fully online 0.0485 m against 0.0495, with a lamp-off lens vignette 0.0357 against 0.0344;
  // README "Illuminator correction", session 16).
  bool lamp_in_traces = false;

  // Initialiser.
  double init_min_parallax_px = 6.0;    // rms translational flow at level 0 for a 640-wide image
  int init_static_frames = 30;          // initialise without parallax after this many frames
  int init_max_frames = 60;             // restart from a new reference frame after this many
  // > 0: a geometric start (geometric_start.hpp) over this many frames after the first gives the
  // initialiser each frame's camera-centre direction after its snap. The frames are held back
  // until then and replayed through the initialiser (and the tracking, once it hands over), so
  // the first pose comes that many frames late; the trajectory still has every frame. When the
  // geometric start fails (too few tracks, a poor fit) the initialiser runs as without it.
  // Plain odometry over the twelve bench sequences: 12 of 12 within 1 % of the path with it
  // (9 without); the 12-run start-offset set 0.73 % (2.36 % without; README "Odometry benchmark").
  int init_geometric_frames = 20;
  // With a geometric start, the keyframes made of held frames held at its poses (priors as firm
  // as the first keyframe's gauge): the hand-over keyframe at the initialiser's pose (the
  // geometric direction, the initialiser's length), later ones at the geometric poses in that
  // scale. Without, the window's first optimisations turned the direction of travel by about
  // 20 degrees on the room's starts from frame 30. The 12-run start-offset set: 0.30 % of the
  // path, 12 of 12 under 1 % (0.70 %, 8 of 12 without; in experiment builds the hand-over
  // keyframe alone 0.56 %, a softer prior of 1e8 on it 0.76 %); plain `bench` 12 of 12 within
  // 1 % either way.
  bool init_hold_geometric_pose = true;
};

struct OdometryFrame {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  cv::Mat image;  // CV_32FC1, 0..255 scale: raw grey, or the photometrically corrected G(I)/V
  // Relative exposure e_t from the photometric calibration, when known: the brightness model
  // between host h and target t then uses e_t / e_h, affine a, b kept near 0 by a strong prior.
  // When absent: plain DSO, affine brightness free (weak prior).
  std::optional<double> exposure;
  // With illuminator_correction: multiplies the exposure. Without it, a lamp that is on (> 0)
  // leaves the affine brightness free as if the exposure were absent (OdometryOptions priors).
  std::optional<double> illuminator_power_w;
  // With illuminator_correction: the lamp's beam exponent m from this frame on, e.g. an online
  // estimate (PhotometricEstimate::beam_exponent), instead of OdometryOptions::beam_exponent.
  // Every residual evaluates the beam with the current m, so a new value applies to the window's
  // keyframes alike.
  std::optional<double> beam_exponent;
  // With illuminator_correction: false while the lamp factor's brightness ratios are not to be
  // trusted (the pipeline: the camera response not yet fitted, so the ratios would go through the
  // wrong curve); the frame then counts as one under a lamp the odometry does not model (factor
  // 1, affine brightness free), as without the correction. The residuals of the window and the
  // tracker follow the newest frame's value.
  bool lamp_factor_trusted = true;
};

enum class TrackingStatus { Initialising, Tracking, Lost, NewSegment };
const char* to_string(TrackingStatus status);

struct OdometryTimings {
  double pyramid_ms = 0.0;
  double tracking_ms = 0.0;  // coarse alignment (or the initialiser) and immature point tracing
  double mapping_ms = 0.0;   // window optimisation + point activation + marginalisation (keyframes)
  double total_ms = 0.0;
};

struct OdometryResult {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  TrackingStatus status = TrackingStatus::Initialising;
  bool is_keyframe = false;
  int segment = 0;                   // increments after every loss + re-initialisation
  std::optional<SE3> T_world_cam;    // empty until initialised, and when lost
  // Of the frame's tracking against its reference keyframe.
  double residual_rms = 0.0;
  int residual_count = 0;
  double affine_a = 0.0;
  double affine_b = 0.0;
  OdometryTimings timings;
  std::string message;               // e.g. why tracking was lost
};

struct KeyframeState {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  int segment = 0;
  SE3 T_world_cam;
  double affine_a = 0.0;
  double affine_b = 0.0;
  bool marginalised = false;
};

struct MapPoint {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  float intensity = 0.0f;  // host image at the point, 0..255
  int segment = 0;
  bool active = false;     // false: marginalised or dropped from the window
};

struct PoseStamped {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  int segment = 0;
  SE3 T_world_cam;
};

class DirectOdometry {
public:
  // `camera` describes the (undistorted) input images.
  explicit DirectOdometry(const PinholeCamera& camera, OdometryOptions options = {});
  ~DirectOdometry();
  DirectOdometry(const DirectOdometry&) = delete;
  DirectOdometry& operator=(const DirectOdometry&) = delete;

  // Throws std::invalid_argument naming the field for an image of the wrong size or type.
  OdometryResult process(const OdometryFrame& frame);

  // Every processed frame with a pose: T_world_kf (latest estimate) * T_kf_frame, as DSO's
  // final output. Frames seen by the initialiser get their poses once it succeeds.
  std::vector<PoseStamped> trajectory() const;
  std::vector<KeyframeState> keyframes() const;
  std::vector<MapPoint> points() const;  // active and marginalised
  // The window's active points only (world frame, current segment) into `out` (cleared first):
  // what the lamp distances and the 3-D view need at every keyframe, without copying the
  // marginalised ones, which grow with the run.
  void active_points(std::vector<Eigen::Vector3d>& out) const;
  void reset();

  const OdometryOptions& options() const { return options_; }
  // Whether the current segment takes the frames' exposures as what changes their brightness
  // (strong affine priors): they carry exposures, and no lamp the odometry does not model is on.
  bool exposure_explains_brightness() const;

private:
  // OdometryOptions::init_geometric_frames: holds `frame` back until the geometric start has its
  // frames, then replays them all; returns the last one's result.
  OdometryResult hold_for_geometric_start(const OdometryFrame& frame);

  struct Impl;
  OdometryOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace nirslam
