#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "commands/subcommand.hpp"
#include "nirslam/sim/sequence_writer.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam::app {
namespace {

struct SimulateOptions {
  std::string scene = "tunnel";
  std::string motion = "handheld";
  std::string camera = "pinhole";
  std::string response = "gamma";
  std::vector<double> response_coefficients;
  std::vector<double> vignette;
  std::vector<double> powers{50.0};
  std::vector<double> light_offset;
  std::vector<double> sweep;
  std::string exposure = "auto";
  std::string texture = "pixel";
  std::filesystem::path out;
  std::optional<std::filesystem::path> contact_sheet;
  std::optional<double> ambient;
  bool capture_rule = false;
  double capture_interval_s = 0.1;
  double capture_distance_m = 0.002;
  bool no_noise = false;
  bool depth = false;
  std::int64_t sweep_viewpoints = 1;
  std::int64_t sweep_stride = 30;
  SimulatorOptions sim;
};

std::vector<double> parse_list(const std::string& text, const char* what) {
  std::vector<double> values;
  std::stringstream stream(text);
  for (std::string item; std::getline(stream, item, ',');) {
    try {
      std::size_t used = 0;
      values.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw CLI::ValidationError(what, "'" + item + "' is not a number");
    }
  }
  return values;
}

SimulatorOptions resolve(SimulateOptions& o) {
  SimulatorOptions s = o.sim;
  const auto scene = sim::parse_scene_kind(o.scene);
  if (!scene) throw std::invalid_argument("--scene: unknown scene '" + o.scene + "' (room, outdoor, parking, tunnel)");
  s.scene = *scene;
  const auto motion = sim::parse_motion_kind(o.motion);
  if (!motion) throw std::invalid_argument("--motion: unknown motion '" + o.motion + "' (handheld, vehicle, robot, tripod)");
  s.motion = *motion;
  if (o.camera == "pinhole") s.camera_model = SimCameraModel::Pinhole;
  else if (o.camera == "fov") s.camera_model = SimCameraModel::Fov;
  else throw std::invalid_argument("--camera: expected pinhole or fov, got '" + o.camera + "'");
  if (!o.response_coefficients.empty()) {
    if (o.response_coefficients.size() != 4) throw std::invalid_argument("--response-coefficients: expected 4 numbers c1,c2,c3,c4");
    s.response = ResponseModel(Eigen::Vector4d(o.response_coefficients[0], o.response_coefficients[1],
                                               o.response_coefficients[2], o.response_coefficients[3]));
  } else {
    const auto preset = parse_response_preset(o.response);
    if (!preset) throw std::invalid_argument("--response: unknown curve '" + o.response + "' (linear, gamma, log, filmic)");
    s.response = ResponseModel::from_preset(*preset);
  }
  if (!o.vignette.empty()) {
    if (o.vignette.size() != 3) throw std::invalid_argument("--vignette: expected 3 numbers v1,v2,v3");
    s.vignette.v = Eigen::Vector3d(o.vignette[0], o.vignette[1], o.vignette[2]);
  }
  if (!o.light_offset.empty()) {
    if (o.light_offset.size() != 3) throw std::invalid_argument("--light-offset: expected 3 numbers x,y,z (metres, camera frame)");
    s.light_offset_cam = Eigen::Vector3d(o.light_offset[0], o.light_offset[1], o.light_offset[2]);
  }
  s.powers_w = o.powers;
  if (o.exposure == "auto") {
    s.exposure_mode = ExposureMode::Auto;
  } else {
    s.exposure_mode = ExposureMode::Fixed;
    try {
      std::size_t used = 0;
      s.exposure_ms = std::stod(o.exposure, &used);
      if (used != o.exposure.size()) throw std::invalid_argument(o.exposure);
    } catch (const std::exception&) {
      throw std::invalid_argument("--exposure: expected 'auto' or milliseconds, got '" + o.exposure + "'");
    }
  }
  if (o.texture == "pixel") s.texture_filtering = TextureFiltering::PixelFootprint;
  else if (o.texture == "distance-independent") s.texture_filtering = TextureFiltering::DistanceIndependent;
  else throw std::invalid_argument("--texture: expected pixel or distance-independent, got '" + o.texture + "'");
  if (o.capture_rule) s.capture_rule = sim::CaptureRule{o.capture_interval_s, o.capture_distance_m};
  if (o.ambient) s.ambient_irradiance = *o.ambient;
  s.noise = !o.no_noise;
  validate(s);
  return s;
}

int run_simulate(SimulateOptions& o) {
  const SimulatorOptions options = resolve(o);
  SimulationOutput output;
  output.write_depth = o.depth;
  output.contact_sheet = o.contact_sheet;
  auto last = std::chrono::steady_clock::now();
  const SimulationProgress progress = [&last](std::int64_t done, std::int64_t total) {
    const auto now = std::chrono::steady_clock::now();
    if (now - last > std::chrono::seconds(1) || done == total) {
      spdlog::info("rendered {}/{}", done, total);
      last = now;
    }
  };
  spdlog::info("simulating {} ({}, seed {}), {}x{}, {} supersampling, response c = [{}, {}, {}, {}]",
               sim::to_string(options.scene), sim::to_string(options.motion), options.seed, options.width, options.height,
               options.supersampling, options.response.coefficients()[0], options.response.coefficients()[1],
               options.response.coefficients()[2], options.response.coefficients()[3]);
  SequenceSummary summary;
  if (!o.sweep.empty()) {
    PowerSweepOptions sweep;
    sweep.powers_w = o.sweep;
    sweep.viewpoints = o.sweep_viewpoints;
    sweep.stride = o.sweep_stride;
    summary = write_power_sweep(options, sweep, o.out, output, progress);
    std::printf("Wrote a power sweep: %lld images (%lld viewpoint(s) x %zu powers), exposure %.3f..%.3f ms, to %s\n",
                static_cast<long long>(summary.images), static_cast<long long>(sweep.viewpoints), sweep.powers_w.size(),
                summary.min_exposure_ms, summary.max_exposure_ms, summary.folder.string().c_str());
  } else {
    summary = write_simulated_sequence(options, o.out, output, progress);
    std::printf("Wrote %lld frames (%.2f s of simulated %s), exposure %.3f..%.3f ms, mean grey %.3f, to %s (%.1f frames/s)\n",
                static_cast<long long>(summary.images), summary.duration_s, std::string(sim::to_string(options.scene)).c_str(),
                summary.min_exposure_ms, summary.max_exposure_ms, summary.mean_grey, summary.folder.string().c_str(),
                summary.render_seconds > 0 ? static_cast<double>(summary.images) / summary.render_seconds : 0.0);
  }
  if (o.contact_sheet) std::printf("Contact sheet: %s\n", o.contact_sheet->string().c_str());
  return 0;
}

}  // namespace

void add_simulate_command(CLI::App& parent, CommandAction& action) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "simulate",
      "Render a simulated near-infrared sequence with full ground truth (TUM monoVO folder + groundtruth.txt/json),\n"
      "to try the pipeline, a lamp power or a camera setting without going into the field");
  cmd->add_option("-o,--out", o->out, "Output folder")->required();
  cmd->add_option("--scene", o->scene, "Scene: room, outdoor, parking or tunnel")->capture_default_str();
  cmd->add_option("--motion", o->motion, "Camera motion: handheld, vehicle, robot or tripod (the rig still)")->capture_default_str();
  cmd->add_option("--seed", o->sim.seed, "Seed: scene details, noise")->capture_default_str();
  cmd->add_option("--frames", o->sim.frames, "Number of frames to render")->capture_default_str()->check(CLI::PositiveNumber);
  cmd->add_option("--fps", o->sim.fps, "Frame rate, Hz")->capture_default_str()->check(CLI::PositiveNumber);
  cmd->add_option_function<std::string>(
         "--power", [o](const std::string& v) { o->powers = parse_list(v, "--power"); },
         "Illuminator power in W (0-150 in the paper); a list cycles every --power-step frames [50]");
  cmd->add_option("--power-step", o->sim.power_step_frames, "Frames per power of a --power list")->capture_default_str();
  cmd->add_option("--width", o->sim.width, "Image width, pixels")->capture_default_str();
  cmd->add_option("--height", o->sim.height, "Image height, pixels")->capture_default_str();
  cmd->add_option("--camera", o->camera, "Lens model: pinhole or fov (wide angle)")->capture_default_str();
  cmd->add_option("--hfov", o->sim.horizontal_fov_deg, "Horizontal field of view, degrees")->capture_default_str();
  cmd->add_option("--omega", o->sim.fov_omega, "FOV model parameter omega (rad)")->capture_default_str();
  cmd->add_option("--supersampling", o->sim.supersampling, "Rays per pixel side (1-4)")->capture_default_str();
  cmd->add_option("--response", o->response, "Response curve: linear, gamma, log, filmic")->capture_default_str();
  cmd->add_option_function<std::string>(
      "--response-coefficients", [o](const std::string& v) { o->response_coefficients = parse_list(v, "--response-coefficients"); },
      "Response coefficients c1,c2,c3,c4 on the sqrt-Legendre basis (instead of --response)");
  cmd->add_option_function<std::string>(
      "--vignette", [o](const std::string& v) { o->vignette = parse_list(v, "--vignette"); },
      "Vignetting v1,v2,v3 of V = 1 + v1 r^2 + v2 r^4 + v3 r^6 [-0.35,0.1,-0.05]");
  cmd->add_option("--bits", o->sim.bit_depth, "Bits per pixel: 8 or 16")->capture_default_str();
  cmd->add_option("--exposure", o->exposure, "'auto' (auto exposure) or a fixed exposure in ms")->capture_default_str();
  cmd->add_option("--max-exposure", o->sim.max_exposure_ms, "Longest exposure, ms (at most the frame period)")->capture_default_str();
  cmd->add_option("--target-grey", o->sim.target_grey, "Auto exposure's mean grey target (0-1)")->capture_default_str();
  cmd->add_option("--ae-swing", o->sim.ae_target_swing,
                  "Auto exposure's wandering target: its irradiance swings by exp(+-S) (0: fixed target)")
      ->capture_default_str();
  cmd->add_option("--ae-period", o->sim.ae_target_period_frames, "Period of the wandering target, frames")->capture_default_str();
  cmd->add_option("--texture", o->texture,
                  "Texture filtering: 'pixel' (to each pixel's footprint, a camera's look) or 'distance-independent' "
                  "(to the fixed --texture-footprint on the surface, no glossy floor: radiance independent of the "
                  "viewpoint, the ground truth of photometric calibration)")
      ->capture_default_str();
  cmd->add_option("--texture-footprint", o->sim.texture_footprint_m, "Finest texture detail of 'distance-independent', m")
      ->capture_default_str();
  cmd->add_option("--max-gain", o->sim.max_gain, "Auto exposure's highest analogue gain (1: exposure only)")->capture_default_str();
  cmd->add_option("--ambient", o->ambient, "Ambient NIR irradiance, W/m^2 (default: the scene's)");
  cmd->add_option("--beam-angle", o->sim.beam_half_angle_deg, "Illuminator half-power half angle, degrees")->capture_default_str();
  cmd->add_option("--efficiency", o->sim.light_efficiency, "Illuminator optical/electrical efficiency")->capture_default_str();
  cmd->add_option_function<std::string>(
      "--light-offset", [o](const std::string& v) { o->light_offset = parse_list(v, "--light-offset"); },
      "Illuminator position in the camera frame x,y,z (m) [0,0.05,0]");
  cmd->add_flag("--no-noise", o->no_noise, "No shot or read noise (quantisation only)");
  cmd->add_flag("--motion-blur", o->sim.motion_blur, "Blur over the exposure (one time per subsample)");
  cmd->add_flag("--capture-rule", o->capture_rule,
                "The paper's capture rule: a frame every --capture-interval s or --capture-distance m of motion");
  cmd->add_option("--capture-interval", o->capture_interval_s, "Capture rule: longest interval, s")->capture_default_str();
  cmd->add_option("--capture-distance", o->capture_distance_m, "Capture rule: motion per frame, m")->capture_default_str();
  cmd->add_flag("--depth", o->depth, "Also write depth/NNNNN.png (16-bit millimetres)");
  cmd->add_option("--contact-sheet", o->contact_sheet, "Also write a PNG with six frames of the sequence");
  cmd->add_option_function<std::string>(
      "--sweep", [o](const std::string& v) { o->sweep = parse_list(v, "--sweep"); },
      "Power sweep: render the same viewpoint(s) at each of these powers (W), e.g. 0,10,20,...,150");
  cmd->add_option("--sweep-viewpoints", o->sweep_viewpoints, "Power sweep: number of viewpoints")->capture_default_str();
  cmd->add_option("--sweep-stride", o->sweep_stride, "Power sweep: frames between viewpoints")->capture_default_str();
  cmd->callback([o, &action] { action = [o] { return run_simulate(*o); }; });
}

}  // namespace nirslam::app
