#include "nirslam/sim/simulator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>

#include <Eigen/Dense>
#include <opencv2/core.hpp>

namespace nirslam {

namespace {

constexpr int kResponseLutSize = 4096;

std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// A standard normal deviate from 64 random bits: four 16-bit uniforms summed (Irwin-Hall),
// centred and scaled to unit variance.
inline float gaussian(std::uint64_t bits) {
  const float sum = static_cast<float>(bits & 0xFFFF) + static_cast<float>((bits >> 16) & 0xFFFF) +
                    static_cast<float>((bits >> 32) & 0xFFFF) + static_cast<float>(bits >> 48);
  constexpr float kScale = 1.0f / 65536.0f;
  return (sum * kScale + 4.0f * 0.5f * kScale - 2.0f) * 1.7320508f;
}

std::shared_ptr<const sim::Scene> make_scene_ptr(const SimulatorOptions& options) {
  validate(options);
  return std::make_shared<const sim::Scene>(sim::make_scene(options.scene, options.seed));
}

}  // namespace

void validate(const SimulatorOptions& o) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("simulator: " + what); };
  if (o.width < 16 || o.height < 16 || o.width > 8192 || o.height > 8192) fail("image size must be 16..8192 pixels a side");
  if (!(o.horizontal_fov_deg > 1.0 && o.horizontal_fov_deg < 170.0)) fail("horizontal field of view must be in (1, 170) degrees");
  if (o.camera_model == SimCameraModel::Fov && !(o.fov_omega > 0.0 && o.fov_omega < std::numbers::pi))
    fail("FOV omega must be in (0, pi)");
  if (o.camera_model == SimCameraModel::Pinhole && o.horizontal_fov_deg >= 160.0) fail("a pinhole camera needs a field of view below 160 degrees");
  if (o.supersampling < 1 || o.supersampling > 4) fail("supersampling must be 1..4");
  if (!(o.fps > 0.0 && o.fps <= 1000.0)) fail("fps must be in (0, 1000]");
  if (o.frames < 0) fail("frames must not be negative");
  if (o.powers_w.empty()) fail("at least one illuminator power is needed");
  for (const double p : o.powers_w)
    if (!(p >= 0.0 && p <= 10000.0)) fail("illuminator power must be 0..10000 W, got " + std::to_string(p));
  if (o.power_step_frames < 0) fail("power step must not be negative");
  if (!(o.light_efficiency > 0.0 && o.light_efficiency <= 1.0)) fail("light efficiency must be in (0, 1]");
  if (!(o.beam_half_angle_deg > 0.5 && o.beam_half_angle_deg < 89.0)) fail("beam half angle must be in (0.5, 89) degrees");
  if (o.ambient_irradiance && !(*o.ambient_irradiance >= 0.0)) fail("ambient irradiance must not be negative");
  if (!o.response.is_monotonic()) fail("the response curve is not monotonic");
  if (!o.vignette.is_plausible()) fail("the vignetting must be positive and fall towards the rim");
  if (o.bit_depth != 8 && o.bit_depth != 16) fail("bit depth must be 8 or 16");
  if (!(o.sensitivity > 0.0)) fail("sensitivity must be positive");
  if (!(o.full_well_e >= 1.0) || !(o.read_noise_e >= 0.0)) fail("full well must be >= 1 and read noise >= 0 electrons");
  if (!(o.min_exposure_ms > 0.0) || !(o.max_exposure_ms >= o.min_exposure_ms)) fail("exposure limits must satisfy 0 < min <= max");
  if (!(o.exposure_ms > 0.0)) fail("exposure must be positive");
  if (!(o.target_grey > 0.01 && o.target_grey < 0.99)) fail("auto-exposure target must be in (0.01, 0.99)");
  if (!(o.ae_damping > 0.0 && o.ae_damping <= 1.0)) fail("auto-exposure damping must be in (0, 1]");
  if (!(o.ae_target_swing >= 0.0 && o.ae_target_swing <= 5.0)) fail("auto-exposure target swing must be in [0, 5]");
  if (!(o.ae_target_period_frames >= 2.0)) fail("auto-exposure target period must be at least 2 frames");
  if (!(o.texture_footprint_m > 0.0 && o.texture_footprint_m <= 10.0)) fail("texture footprint must be in (0, 10] m");
  if (!(o.max_gain >= 1.0)) fail("maximum gain must be at least 1");
  if (o.capture_rule && (!(o.capture_rule->max_interval_s > 0.0) || !(o.capture_rule->max_distance_m > 0.0)))
    fail("capture rule interval and distance must be positive");
}

std::shared_ptr<const CameraModel> make_sim_camera(const SimulatorOptions& o) {
  const double half = 0.5 * o.horizontal_fov_deg * std::numbers::pi / 180.0;
  const double cx = 0.5 * (o.width - 1), cy = 0.5 * (o.height - 1);
  if (o.camera_model == SimCameraModel::Pinhole) {
    const double f = 0.5 * o.width / std::tan(half);
    return std::make_shared<PinholeCamera>(o.width, o.height, Eigen::Vector4d(f, f, cx, cy));
  }
  // FOV model: the ray at half the field of view lands on the image's side edge.
  const double r_u = std::tan(half);
  const double r_d = std::atan(2.0 * r_u * std::tan(0.5 * o.fov_omega)) / o.fov_omega;
  const double f = 0.5 * o.width / r_d;
  return std::make_shared<FovCamera>(o.width, o.height, Eigen::Vector4d(f, f, cx, cy), o.fov_omega);
}

Simulator::Simulator(SimulatorOptions options)
    : options_(std::move(options)),
      scene_(make_scene_ptr(options_)),
      camera_(make_sim_camera(options_)),
      trajectory_(sim::make_trajectory(options_.scene, options_.motion, options_.seed)),
      renderer_(scene_, camera_, options_.supersampling, shading_options(options_)) {
  vignette_map_ = options_.vignette.render(options_.width, options_.height);
  response_lut_.resize(kResponseLutSize + 1);
  for (int i = 0; i <= kResponseLutSize; ++i) {
    const double u = static_cast<double>(i) / kResponseLutSize;
    response_lut_[static_cast<std::size_t>(i)] = static_cast<float>(options_.response(u * u));
  }
  rewind();
}

sim::ShadingOptions Simulator::shading_options(const SimulatorOptions& options) {
  sim::ShadingOptions shading;
  if (options.texture_filtering == TextureFiltering::DistanceIndependent) {
    shading.texture_footprint_m = options.texture_footprint_m;
    shading.glossy_floor = false;
  }
  return shading;
}

sim::Lighting Simulator::lighting(double power_w) const {
  sim::Lighting l;
  l.illuminator.power_w = power_w;
  l.illuminator.efficiency = options_.light_efficiency;
  l.illuminator.half_angle_deg = options_.beam_half_angle_deg;
  l.illuminator.offset_cam = options_.light_offset_cam;
  l.ambient_irradiance = options_.ambient_irradiance.value_or(scene_->typical_ambient_irradiance);
  l.sky_radiance = scene_->sky_radiance;
  return l;
}

std::optional<std::int64_t> Simulator::frame_count() const {
  if (options_.frames > 0) return options_.frames;
  return std::nullopt;
}

double Simulator::frame_time(std::int64_t index) {
  if (!options_.capture_rule) return static_cast<double>(index) / options_.fps;
  if (index >= static_cast<std::int64_t>(times_.size())) {
    const std::int64_t want = std::max<std::int64_t>(index + 1, 2 * static_cast<std::int64_t>(times_.size()));
    times_ = sim::frame_times(trajectory_, want, options_.fps, options_.capture_rule);
  }
  return times_[static_cast<std::size_t>(index)];
}

double Simulator::power_at(std::int64_t index) const {
  const auto& p = options_.powers_w;
  if (p.size() == 1 || options_.power_step_frames <= 0) return p.front();
  return p[static_cast<std::size_t>((index / options_.power_step_frames) % static_cast<std::int64_t>(p.size()))];
}

void Simulator::rewind() {
  index_ = 0;
  exposure_ms_ = std::clamp(options_.exposure_ms, options_.min_exposure_ms,
                            std::min(options_.max_exposure_ms, 1000.0 / options_.fps));
  if (options_.exposure_mode == ExposureMode::Fixed) exposure_ms_ = options_.exposure_ms;
  gain_ = 1.0;
  exposure_mode_ = options_.exposure_mode;
}

void Simulator::set_exposure(ExposureMode mode, double exposure_ms, double gain) {
  exposure_mode_ = mode;
  exposure_ms_ = exposure_ms;
  gain_ = gain;
}

void Simulator::render_radiance(double t, double exposure_ms, double power_w, cv::Mat& radiance, cv::Mat* depth) const {
  const sim::Lighting light = lighting(power_w);
  if (!options_.motion_blur || renderer_.time_slots() == 1) {
    const SE3 pose = trajectory_.pose(t);
    renderer_.render(std::span<const SE3>(&pose, 1), light, radiance, depth);
    return;
  }
  const int slots = renderer_.time_slots();
  std::vector<SE3> poses;
  const double e = exposure_ms * 1e-3;
  for (int k = 0; k < slots; ++k) poses.push_back(trajectory_.pose(t + ((k + 0.5) / slots - 0.5) * e));
  renderer_.render(poses, light, radiance, depth);
}

VignetteModel Simulator::halo_factor() const {
  const sim::Illuminator light = lighting(0.0).illuminator;
  const Eigen::Vector2d centre(0.5 * (options_.width - 1), 0.5 * (options_.height - 1));
  constexpr int kRadii = 64;
  Eigen::Matrix<double, kRadii, 3> A;
  Eigen::Matrix<double, kRadii, 1> b;
  for (int i = 0; i < kRadii; ++i) {
    const double r = (i + 0.5) / kRadii;  // along the diagonal: radius 1 at the corner
    const Eigen::Vector2d pixel = centre + r * centre;
    const auto ray = camera_->unproject(pixel);
    const double alpha = ray ? std::acos(std::clamp(ray->normalized().z(), -1.0, 1.0)) : 0.5 * std::numbers::pi;
    const double r2 = r * r;
    A.row(i) << r2, r2 * r2, r2 * r2 * r2;
    b[i] = options_.vignette(r) * light.beam(alpha) - 1.0;
  }
  return VignetteModel{A.colPivHouseholderQr().solve(b)};
}

std::optional<double> Simulator::light_distance(const cv::Mat& depth, const Eigen::Vector2d& pixel) const {
  const int x = static_cast<int>(std::lround(pixel.x())), y = static_cast<int>(std::lround(pixel.y()));
  if (depth.type() != CV_32FC1 || x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) return std::nullopt;
  const double z = depth.at<float>(y, x);
  const auto ray = camera_->unproject(pixel);
  if (!(z > 0.0) || !ray || !(ray->z() > 0.0)) return std::nullopt;
  return ((z / ray->z()) * *ray - options_.light_offset_cam).norm();
}

Frame Simulator::expose(const cv::Mat& radiance, double exposure_ms, double gain, std::uint64_t noise_key,
                        double* mean_grey) const {
  CV_Assert(radiance.type() == CV_32FC1 && radiance.size() == vignette_map_.size());
  Frame frame;
  const bool sixteen = options_.bit_depth == 16;
  frame.image.create(radiance.size(), sixteen ? CV_16UC1 : CV_8UC1);
  frame.bit_depth = options_.bit_depth;
  frame.exposure_ms = exposure_ms;
  frame.gain = gain;
  const float scale = static_cast<float>(options_.sensitivity * exposure_ms * 1e-3);
  const float full_well = static_cast<float>(options_.full_well_e);
  const float read2 = static_cast<float>(options_.read_noise_e * options_.read_noise_e);
  const float g = static_cast<float>(gain);
  const float top = sixteen ? 65535.0f : 255.0f;
  const bool noise = options_.noise;
  const std::uint64_t key = mix64(mix64(options_.seed ^ 0xA0761D6478BD642Full) + noise_key);
  const float* lut = response_lut_.data();
  std::vector<double> row_sums(static_cast<std::size_t>(radiance.rows), 0.0);
  cv::parallel_for_(cv::Range(0, radiance.rows), [&](const cv::Range& range) {
    for (int y = range.start; y < range.end; ++y) {
      const float* L = radiance.ptr<float>(y);
      const float* V = vignette_map_.ptr<float>(y);
      double sum = 0.0;
      for (int x = 0; x < radiance.cols; ++x) {
        float electrons = std::min(scale * V[x] * L[x], 1.0f) * full_well;
        if (noise) {
          const std::uint64_t pixel = static_cast<std::uint64_t>(y) * static_cast<std::uint64_t>(radiance.cols) + static_cast<std::uint64_t>(x);
          electrons += std::sqrt(electrons + read2) * gaussian(mix64(key + pixel * 0x9E3779B97F4A7C15ull));
        }
        const float X = std::clamp(g * electrons / full_well, 0.0f, 1.0f);
        const float u = std::sqrt(X) * kResponseLutSize;
        const int i = std::min(static_cast<int>(u), kResponseLutSize - 1);
        const float f = lut[i] + (lut[i + 1] - lut[i]) * (u - static_cast<float>(i));
        const float level = static_cast<float>(static_cast<int>(std::clamp(f, 0.0f, 1.0f) * top + 0.5f));
        sum += level;
        if (sixteen)
          frame.image.ptr<std::uint16_t>(y)[x] = static_cast<std::uint16_t>(level);
        else
          frame.image.ptr<std::uint8_t>(y)[x] = static_cast<std::uint8_t>(level);
      }
      row_sums[static_cast<std::size_t>(y)] = sum;
    }
  });
  if (mean_grey) {
    double total = 0.0;
    for (const double s : row_sums) total += s;  // in row order: the same sum on every run
    *mean_grey = total / (static_cast<double>(radiance.total()) * top);
  }
  return frame;
}

std::pair<double, double> Simulator::auto_exposure_step(double exposure_ms, double gain, double mean_grey,
                                                        std::int64_t frame) const {
  const ResponseModel& f = options_.response;
  const double measured = f.inverse(std::max(mean_grey, 0.5 / 255.0));
  double wanted = f.inverse(options_.target_grey);
  if (options_.ae_target_swing > 0.0)
    wanted *= std::exp(options_.ae_target_swing *
                       std::sin(2.0 * std::numbers::pi * static_cast<double>(frame) / options_.ae_target_period_frames));
  double ratio = std::clamp(wanted / std::max(measured, 1e-9), 0.5, 2.0);
  if (std::fabs(std::log(ratio)) < 0.02) return {exposure_ms, gain};
  double step = std::pow(ratio, options_.ae_damping);
  const double max_exposure = std::min(options_.max_exposure_ms, 1000.0 / options_.fps);
  if (step < 1.0 && gain > 1.0) {  // darker: lower the gain first
    const double new_gain = std::max(1.0, gain * step);
    step /= new_gain / gain;
    gain = new_gain;
  }
  double exposure = exposure_ms * step;
  if (exposure > max_exposure) {  // brighter beyond the longest exposure: raise the gain
    gain = std::min(options_.max_gain, gain * exposure / max_exposure);
    exposure = max_exposure;
  }
  return {std::max(exposure, options_.min_exposure_ms), gain};
}

std::optional<SimulatedFrame> Simulator::next(bool with_depth) {
  if (options_.frames > 0 && index_ >= options_.frames) return std::nullopt;
  const std::int64_t i = index_;
  const double t = frame_time(i);
  const double power = power_override_.value_or(power_at(i));
  SimulatedFrame out;
  render_radiance(t, exposure_ms_, power, out.radiance, with_depth ? &out.depth : nullptr);
  out.frame = expose(out.radiance, exposure_ms_, gain_, static_cast<std::uint64_t>(i), &out.mean_grey);
  out.frame.timestamp_s = t;
  out.frame.index = i;
  out.frame.illuminator_power_w = power;
  char name[64];
  std::snprintf(name, sizeof name, "sim-%s/%05lld", std::string(to_string(options_.scene)).c_str(), static_cast<long long>(i));
  out.frame.name = name;
  out.T_world_cam = trajectory_.pose(t);
  if (exposure_mode_ == ExposureMode::Auto)
    std::tie(exposure_ms_, gain_) = auto_exposure_step(exposure_ms_, gain_, out.mean_grey, i);
  ++index_;
  return out;
}

// ---------------------------------------------------------------------------------------------

namespace {
bool lamp_in_schedule(const SimulatorOptions& o) {
  return std::any_of(o.powers_w.begin(), o.powers_w.end(), [](double p) { return p > 0.0; });
}
}  // namespace

SimulatedSource::SimulatedSource(const SimulatorOptions& options) : simulator_(options) {
  info_.kind = "sim";
  info_.scene_type = std::string(sim::to_string(simulator_.options().scene));
  const SimulatorOptions& o = simulator_.options();
  info_.description = "simulated " + std::string(sim::to_string(o.scene)) + ", " + std::string(sim::to_string(o.motion)) +
                      ", " + std::to_string(static_cast<int>(std::lround(o.powers_w.front()))) + " W, seed " +
                      std::to_string(o.seed);
  if (o.frames > 0) info_.frame_count = static_cast<std::size_t>(o.frames);
  info_.live = false;
  info_.nominal_fps = o.capture_rule ? 1.0 / o.capture_rule->max_interval_s : o.fps;
  info_.reports_lamp_power = lamp_in_schedule(o);
  IlluminatorCapabilities lamp;
  lamp.description = "the simulator's illuminator";
  lamp.reads_back = true;
  lamp_ = std::make_shared<ManualIlluminator>(lamp);

  controls_ = std::make_shared<CameraControlHub>("sim:" + info_.scene_type);
  controls_->fix_frame_rate("the simulated camera's frame rate is its sequence's");
  controls_->update([&](CameraState& c) {
    c.card = "simulated NIR camera";
    c.width = o.width;
    c.height = o.height;
    c.bit_depth = o.bit_depth;
    c.format = std::string(o.bit_depth == 16 ? "Y16 " : "GREY ") + std::to_string(o.width) + "x" + std::to_string(o.height);
    c.fps = o.fps;
    c.rates_fps = {o.fps};
    c.connection = CameraConnection::Streaming;
    c.exposure_ms = {true, o.min_exposure_ms, std::min(o.max_exposure_ms, 1000.0 / o.fps), 0.0, o.exposure_ms};
    c.gain = {o.max_gain > 1.0, 1.0, o.max_gain, 0.0, 1.0};
    c.gain_unity = 1.0;
    c.auto_exposure_available = true;
    c.auto_exposure = o.exposure_mode == ExposureMode::Auto;
  });
}

// The controls' changes, as a camera's driver would take them before the next frame; a lock holds
// what is in effect.
void SimulatedSource::apply_camera_controls() {
  const PendingCameraControls p = controls_->take_pending();
  if (!p.any()) return;
  ExposureMode mode = simulator_.current_exposure_mode();
  double exposure_ms = simulator_.current_exposure_ms();
  double gain = simulator_.current_gain();
  if (p.auto_exposure) mode = *p.auto_exposure ? ExposureMode::Auto : ExposureMode::Fixed;
  if (p.locked && *p.locked) mode = ExposureMode::Fixed;
  if (p.exposure_ms) {
    mode = ExposureMode::Fixed;
    exposure_ms = *p.exposure_ms;
  }
  if (p.gain) gain = *p.gain;
  simulator_.set_exposure(mode, exposure_ms, gain);
  controls_->update([&](CameraState& c) {
    c.auto_exposure = mode == ExposureMode::Auto;
    if (p.locked) c.locked = *p.locked;
  });
}

void SimulatedSource::rewind() {
  simulator_.rewind();
  // The operator's settings outlast a rewind, as a camera's do: held values stay held.
  const CameraState c = controls_->state();
  if (!c.auto_exposure && c.exposure_in_effect_ms)
    simulator_.set_exposure(ExposureMode::Fixed, *c.exposure_in_effect_ms, c.gain_in_effect.value_or(1.0));
  else if (c.auto_exposure)
    simulator_.set_exposure(ExposureMode::Auto, simulator_.current_exposure_ms(), simulator_.current_gain());
  controls_->update([](CameraState& s) { s.connection = CameraConnection::Streaming; });
  last_frame_at_.reset();
}

std::optional<PhotometricTruth> SimulatedSource::photometric_truth() const {
  const SimulatorOptions& o = simulator_.options();
  PhotometricTruth truth{o.response, o.vignette, std::nullopt};
  // The operator may change the power while it runs; the schedule says whether the lamp is part
  // of the scene at all.
  if (lamp_in_schedule(o)) truth.halo = simulator_.halo_factor();
  return truth;
}

std::optional<Frame> SimulatedSource::next() {
  if (const auto power_w = lamp_->current_power_w()) simulator_.set_power(*power_w);
  apply_camera_controls();
  std::optional<SimulatedFrame> f = simulator_.next(false);
  if (!f) {
    controls_->update([](CameraState& c) { c.connection = CameraConnection::Stopped; });
    return std::nullopt;
  }
  // The rate frames are taken at: the worker's pace (recorded speed or as fast as it can).
  const auto now = std::chrono::steady_clock::now();
  const double dt = last_frame_at_ ? std::chrono::duration<double>(now - *last_frame_at_).count() : 0.0;
  last_frame_at_ = now;
  controls_->update([&](CameraState& c) {
    c.exposure_in_effect_ms = f->frame.exposure_ms;
    c.gain_in_effect = f->frame.gain;
    ++c.frames_captured;
    if (dt > 0.0) c.measured_fps = c.measured_fps > 0.0 ? 0.9 * c.measured_fps + 0.1 / dt : 1.0 / dt;
  });
  last_pose_ = f->T_world_cam;
  f->frame.T_world_cam_truth = f->T_world_cam;
  return std::move(f->frame);
}

std::unique_ptr<Source> make_simulated_source(const SimulatorOptions& options) {
  return std::make_unique<SimulatedSource>(options);
}

}  // namespace nirslam
