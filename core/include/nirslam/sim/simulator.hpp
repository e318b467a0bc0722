#pragma once

// The ground-truth NIR sequence simulator: scene + trajectory + illuminator + camera (response,
// vignetting, noise, auto exposure) -> frames whose every parameter is known. Deterministic for
// a seed: the noise of frame i comes from a counter-based hash of (seed, i, pixel), so rewinding
// or rendering on another thread count gives the same bytes.
//
// Sensor model, per pixel x of frame i (exposure e_i in seconds, analogue gain g_i):
//   X_pre = k * e_i * V(x) * L(x)                 fraction of the full well; L is the radiance
//                                                  from the renderer, k = sensitivity
//   n     = min(X_pre, 1) * full_well             signal electrons
//   n'    = n + sqrt(n + read_noise^2) * N(0, 1)  shot and read noise (Gaussian approximation)
//   X     = clamp(g_i * n' / full_well, 0, 1)
//   I(x)  = round(f(X) * (2^bits - 1))            response, quantisation to 8 or 16 bits
// so without noise G(I) = f^-1(I / (2^bits - 1)) = g_i * k * e_i * V(x) * L(x) to within
// quantisation. N(0, 1) is approximated by a scaled sum of four uniforms (Irwin-Hall: exact
// variance, tails cut at 3.5 sigma).
//
// Auto exposure, as camera firmware does it: after each frame, the mean grey m is compared with
// the target; the exposure is multiplied by (G(target) / G(m))^damping (the ratio clamped to
// [0.5, 2], a 2 % dead band), kept within [min, max] exposure (max at most the frame period);
// beyond the longest exposure the gain rises up to max_gain, and falls first when it is brighter.
// A wandering target (ae_target_swing > 0) scales G(target) of frame i by
// exp(swing * sin(2 pi i / ae_target_period_frames)): the exposure then keeps swinging over a
// range of about exp(2 swing), as in the auto-exposure videos photometric calibration is made for
// (a settled auto exposure hardly varies, which leaves the response unobservable).
//
// Texture filtering: PixelFootprint (default) band-limits the texture to each pixel's footprint,
// the look of a real camera, but a surface point's radiance then depends on the viewing distance.
// DistanceIndependent filters it to the fixed texture_footprint_m on the surface (and drops the
// glossy floor's view-dependent mirror term), so with the lamp off a point's radiance is the same
// from every pose: the ground truth of photometric calibration. Surfaces where a pixel covers more
// than texture_footprint_m (beyond about texture_footprint_m * fx metres at normal incidence, or
// at grazing angles) alias with supersampling 1.

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/capture/control_hub.hpp"
#include "nirslam/geometry/se3.hpp"
#include "nirslam/illumination/illuminator.hpp"
#include "nirslam/image/frame.hpp"
#include "nirslam/photometric/response_model.hpp"
#include "nirslam/sim/renderer.hpp"
#include "nirslam/sim/scene.hpp"
#include "nirslam/sim/trajectory.hpp"
#include "nirslam/sources/source.hpp"

namespace nirslam {

enum class SimCameraModel { Pinhole, Fov };
enum class ExposureMode { Auto, Fixed };
enum class TextureFiltering { PixelFootprint, DistanceIndependent };

struct SimulatorOptions {
  sim::SceneKind scene = sim::SceneKind::Tunnel;
  sim::MotionKind motion = sim::MotionKind::Handheld;
  std::uint32_t seed = 1;

  // Camera geometry and timing.
  int width = 640;
  int height = 480;
  SimCameraModel camera_model = SimCameraModel::Pinhole;
  double horizontal_fov_deg = 75.0;  // sets fx = fy
  double fov_omega = 0.9;            // FOV model's omega (rad)
  int supersampling = 2;             // rays per pixel side, 1..4
  double fps = 30.0;
  std::int64_t frames = 300;         // 0: endless (as a source)
  std::optional<sim::CaptureRule> capture_rule;  // instead of a fixed frame rate
  bool motion_blur = false;          // one time per subsample across the exposure
  TextureFiltering texture_filtering = TextureFiltering::PixelFootprint;  // see above
  double texture_footprint_m = 0.05;  // DistanceIndependent: the finest texture detail, metres

  // Illuminator and ambient light.
  std::vector<double> powers_w{50.0};  // cycled every power_step_frames (one value: constant)
  std::int64_t power_step_frames = 0;
  double light_efficiency = 0.35;
  double beam_half_angle_deg = 30.0;
  Eigen::Vector3d light_offset_cam = Eigen::Vector3d(0.0, 0.05, 0.0);
  std::optional<double> ambient_irradiance;  // W m^-2; default: the scene's typical value

  // Sensor.
  ResponseModel response = ResponseModel::from_preset(ResponsePreset::Gamma);
  VignetteModel vignette{Eigen::Vector3d(-0.35, 0.10, -0.05)};
  int bit_depth = 8;              // 8 or 16
  double sensitivity = 400.0;     // full-well fractions per (W m^-2 sr^-1 s)
  double full_well_e = 10000.0;
  double read_noise_e = 4.0;
  bool noise = true;

  // Exposure.
  ExposureMode exposure_mode = ExposureMode::Auto;
  double exposure_ms = 10.0;      // fixed value, or where auto exposure starts
  double min_exposure_ms = 0.05;
  double max_exposure_ms = 30.0;  // capped at the frame period
  double target_grey = 0.35;      // auto exposure's mean grey target, fraction of full scale
  double ae_damping = 0.35;
  double ae_target_swing = 0.0;          // wandering target (see above); 0: fixed target
  double ae_target_period_frames = 60.0;
  double max_gain = 1.0;          // 1: exposure only
};

// Checks the options; throws std::invalid_argument naming the bad one.
void validate(const SimulatorOptions& options);

// The camera model the options describe.
std::shared_ptr<const CameraModel> make_sim_camera(const SimulatorOptions& options);

// One rendered frame and its ground truth.
struct SimulatedFrame {
  Frame frame;           // image, timestamp, exposure, gain, power
  SE3 T_world_cam;       // at the frame's timestamp (the middle of the exposure)
  cv::Mat radiance;      // CV_32FC1, W m^-2 sr^-1, averaged over each pixel (before V, e, gain)
  cv::Mat depth;         // CV_32FC1 z in metres of each pixel's centre ray, when asked for
  double mean_grey = 0.0;  // mean of the image, fraction of full scale
};

class Simulator {
public:
  explicit Simulator(SimulatorOptions options);

  const SimulatorOptions& options() const { return options_; }
  const sim::Scene& scene() const { return *scene_; }
  const sim::Trajectory& trajectory() const { return trajectory_; }
  const sim::Renderer& renderer() const { return renderer_; }
  std::shared_ptr<const CameraModel> camera() const { return camera_; }
  const cv::Mat& vignette_map() const { return vignette_map_; }  // CV_32FC1, V(x)
  sim::Lighting lighting(double power_w) const;

  std::optional<std::int64_t> frame_count() const;
  double frame_time(std::int64_t index);  // s; extends the capture-rule schedule as needed
  double power_at(std::int64_t index) const;
  // Overrides the power schedule from the next frame on (the operator's "set power").
  void set_power(std::optional<double> power_w) { power_override_ = power_w; }

  // The next frame of the sequence; advances the auto exposure. std::nullopt at the end.
  std::optional<SimulatedFrame> next(bool with_depth = false);
  std::int64_t next_index() const { return index_; }
  void rewind();
  double current_exposure_ms() const { return exposure_ms_; }
  double current_gain() const { return gain_; }
  ExposureMode current_exposure_mode() const { return exposure_mode_; }
  // From the next frame on: auto exposure from the current values, or these held (a camera's
  // controls: SimulatedSource). rewind() goes back to the options' mode and start.
  void set_exposure(ExposureMode mode, double exposure_ms, double gain);

  // Renders the radiance at `pose` (with motion blur over exposure_ms when enabled).
  void render_radiance(double t, double exposure_ms, double power_w, cv::Mat& radiance, cv::Mat* depth = nullptr) const;
  // The halo factor H = V B the calibration estimates under the co-located lamp: the lens
  // vignetting times the beam pattern cos^m(alpha) at the pixel's angle alpha off the axis
  // (renderer.hpp), fitted by the radial polynomial in least squares over 64 radii.
  VignetteModel halo_factor() const;
  // Ground truth for the illuminator-aware calibration: the distance in metres from the lamp to
  // the surface seen at `pixel`, from a depth map of next(true) (nearest pixel); std::nullopt
  // outside the image or where the ray left the scene.
  std::optional<double> light_distance(const cv::Mat& depth, const Eigen::Vector2d& pixel) const;
  // The sensor: radiance -> image, with noise drawn from (seed, noise_key, pixel).
  Frame expose(const cv::Mat& radiance, double exposure_ms, double gain, std::uint64_t noise_key,
               double* mean_grey = nullptr) const;
  // One auto-exposure step from the mean grey of the last frame: the next (exposure, gain).
  // `frame` is the index of the last frame (for the wandering target).
  std::pair<double, double> auto_exposure_step(double exposure_ms, double gain, double mean_grey,
                                               std::int64_t frame = 0) const;
  // The renderer's shading options these simulator options ask for.
  static sim::ShadingOptions shading_options(const SimulatorOptions& options);

private:
  SimulatorOptions options_;
  std::shared_ptr<const sim::Scene> scene_;
  std::shared_ptr<const CameraModel> camera_;
  sim::Trajectory trajectory_;
  sim::Renderer renderer_;
  cv::Mat vignette_map_;
  std::vector<float> response_lut_;  // f on a grid of sqrt(X)
  std::vector<double> times_;
  std::optional<double> power_override_;
  std::int64_t index_ = 0;
  double exposure_ms_ = 0.0;
  double gain_ = 1.0;
  ExposureMode exposure_mode_ = ExposureMode::Auto;
};

// The simulator as a Source (the GUI and worker run on it live). Frames carry exposure_ms, gain
// and illuminator_power_w; camera() is the simulated camera; rewind() gives the same frames again.
class SimulatedSource final : public Source {
public:
  explicit SimulatedSource(const SimulatorOptions& options);
  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override;
  void rewind() override;
  std::shared_ptr<const CameraModel> camera() const override { return simulator_.camera(); }
  // The simulated lamp: a power set here (the operator's, or the sweep wizard's) replaces the
  // options' power schedule from the next frame on.
  std::shared_ptr<IlluminatorController> illuminator() const override { return lamp_; }
  std::optional<PhotometricTruth> photometric_truth() const override;

  // The simulated camera's exposure, gain, auto exposure and lock, as a V4L2 camera offers them
  // (the GUI's Camera tab, the power sweep's lock); changes take effect from the next frame, and
  // a rewind keeps them.
  std::shared_ptr<CameraControls> camera_controls() const override { return controls_; }

  Simulator& simulator() { return simulator_; }
  const Simulator& simulator() const { return simulator_; }
  // Ground truth of the frame last returned by next().
  const std::optional<SE3>& last_pose() const { return last_pose_; }

private:
  Simulator simulator_;
  SourceInfo info_;
  void apply_camera_controls();

  std::optional<SE3> last_pose_;
  std::shared_ptr<ManualIlluminator> lamp_;
  std::shared_ptr<CameraControlHub> controls_;
  std::optional<std::chrono::steady_clock::time_point> last_frame_at_;
};

std::unique_ptr<Source> make_simulated_source(const SimulatorOptions& options = {});

}  // namespace nirslam
