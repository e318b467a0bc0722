#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/source_argument.hpp"
#include "commands/subcommand.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/photometric/beam_from_halo.hpp"
#include "nirslam/photometric/calibration_output.hpp"
#include "nirslam/photometric/exposure_scale.hpp"
#include "nirslam/photometric/grey_range_advice.hpp"
#include "nirslam/photometric/online_calibration.hpp"
#include "nirslam/sim/simulator.hpp"
#include "nirslam/sources/frame_limit.hpp"

namespace nirslam::app {
namespace {

namespace fs = std::filesystem;

struct CalibrateOptions {
  std::string source;
  fs::path out_dir;
  std::int64_t max_frames = 0;
  fs::path json_file;
  bool ignore_reported_exposures = false;
  fs::path lens_vignette;  // vignette.png of an earlier calibration without the lamp
};

// The lamp's beam: the estimated halo factor over the lens vignetting known from before.
void write_beam(const fs::path& lens_file, const PhotometricEstimate& estimate, const Source& source,
                const fs::path& out_dir) {
  const std::shared_ptr<const CameraModel> camera = source.camera();
  if (!camera)
    throw InputError(lens_file.string(), "separating the beam needs the camera's intrinsics, and the sequence has none");
  const cv::Mat lens = read_vignette_png(lens_file);
  if (lens.cols != camera->width() || lens.rows != camera->height())
    throw InputError(lens_file.string(), fmt::format("the lens vignette is {}x{}, the frames are {}x{}", lens.cols,
                                                     lens.rows, camera->width(), camera->height()));
  const cv::Mat halo = estimate.vignette.render(camera->width(), camera->height());
  const BeamFit fit = fit_beam_from_halo(halo, lens, *camera);
  write_vignette_png(out_dir / "beam.png", beam_pattern(halo, lens));
  const nlohmann::json beam = {{"lens_vignette", lens_file.string()},
                               {"determined", fit.ok},
                               {"reason", fit.reason},
                               {"beam_exponent", fit.beam_exponent},
                               {"half_angle_deg", fit.half_angle_deg},
                               {"rms_log", fit.rms_log},
                               {"max_alpha_deg", fit.max_alpha_deg},
                               {"samples", fit.samples}};
  std::ofstream out(out_dir / "beam.json");
  out << beam.dump(2) << '\n';
  if (!out) throw std::runtime_error((out_dir / "beam.json").string() + ": cannot write");
  if (fit.ok)
    std::printf("  lamp beam (halo factor / lens vignette): cos(alpha)^%.2f, half angle %.1f degrees, rms %.3f in log "
                "(odometry.beam_exponent)\n", fit.beam_exponent, fit.half_angle_deg, fit.rms_log);
  else
    std::printf("  lamp beam not determined: %s\n", fit.reason.c_str());
  std::printf("  wrote beam.png and beam.json in %s\n", out_dir.string().c_str());
}

// Ground truth of a built-in simulated sequence: the simulator's default options for the scene
// (as source_factory_from_argument builds them); per-frame exposures are collected while running.
std::optional<PhotometricGroundTruth> built_in_truth(const std::string& argument) {
  if (argument != "sim" && argument.rfind("sim:", 0) != 0) return std::nullopt;
  const SimulatorOptions defaults;
  PhotometricGroundTruth truth;
  truth.response = defaults.response;
  truth.vignette = defaults.vignette;
  return truth;
}

int run_calibrate(const CalibrateOptions& options) {
  SourceFactory factory = source_factory_from_argument(options.source);
  if (options.max_frames > 0) factory = [factory, n = options.max_frames] { return limit_frames(factory(), n); };
  std::optional<PhotometricGroundTruth> truth =
      is_built_in_sequence(options.source) ? built_in_truth(options.source) : read_simulated_ground_truth(options.source);
  const bool collect_truth = truth.has_value() && truth->exposures.empty();

  const auto started = std::chrono::steady_clock::now();
  // The config's calibration section (--config), as `run` uses it: e.g. background_thread: false
  // makes the batch repeatable to the bit.
  OnlineCalibrationOptions calibration_options = app_config().worker.pipeline.calibration;
  calibration_options.correct_images = false;  // batch: only the model and the exposures are wanted
  calibration_options.use_reported_exposures = !options.ignore_reported_exposures;
  std::unique_ptr<Source> source = factory();
  CalibrationOutputInfo info;
  info.source = options.source;
  double front_end_ms = 0.0;
  std::shared_ptr<const PhotometricEstimate> estimate;
  {
    // Pass 1: the online calibration over the whole sequence, then the final optimisation.
    OnlinePhotometricCalibration calibration(calibration_options);
    while (std::optional<Frame> frame = source->next()) {
      if (collect_truth && frame->exposure_ms)
        truth->exposures.emplace_back(frame->index, *frame->exposure_ms * frame->gain.value_or(1.0));
      if (options.ignore_reported_exposures) frame->exposure_ms.reset();
      info.width = frame->width();
      info.height = frame->height();
      front_end_ms += calibration.process(*frame).front_end_ms;
      ++info.frames;
      if (info.frames % 100 == 0) spdlog::info("frame {}: {}", info.frames, calibration.estimate()->status);
    }
    if (info.frames == 0) throw InputError(options.source, "the sequence holds no frames");
    calibration.finish();
    estimate = calibration.estimate();
  }
  // Pass 2: every frame's exposure again with the final model (front end only), so early frames
  // are not judged with the initial response.
  OnlineCalibrationOptions second = calibration_options;
  second.run_backend = false;
  second.background_thread = false;
  second.backend.initial_response = estimate->response;
  second.backend.initial_vignette = estimate->vignette;
  second.backend.estimate_response = false;
  // The exposure estimator trusts G where the fit saw data (the extrapolated ends are down-weighted).
  if (estimate->grey_high > estimate->grey_low) second.initial_grey_range = {estimate->grey_low, estimate->grey_high};
  OnlinePhotometricCalibration exposures(second);
  source->rewind();
  while (std::optional<Frame> frame = source->next()) {
    if (options.ignore_reported_exposures) frame->exposure_ms.reset();
    exposures.process(*frame);
  }
  info.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  info.mean_front_end_ms = front_end_ms / static_cast<double>(info.frames);

  std::optional<PhotometricErrors> errors;
  if (truth && !truth->exposures.empty())
    errors = compare_with_ground_truth(estimate->response, estimate->vignette, exposures.exposure_history(), *truth,
                                       info.width, info.height);

  const Eigen::Vector4d& c = estimate->response.coefficients();
  std::printf("Photometric calibration of %s: %lld frames (%dx%d) in %.1f s, front end %.2f ms/frame\n",
              options.source.c_str(), static_cast<long long>(info.frames), info.width, info.height, info.wall_time_s,
              info.mean_front_end_ms);
  std::printf("  ambiguity resolution: %s (%s)\n", std::string(to_string(estimate->ambiguity)).c_str(),
              estimate->ambiguity_detail.c_str());
  std::printf("  status: %s\n", estimate->status.c_str());
  std::printf("  response c = %.6f %.6f %.6f %.6f, vignette v = %.6f %.6f %.6f\n", c[0], c[1], c[2], c[3],
              estimate->vignette.v[0], estimate->vignette.v[1], estimate->vignette.v[2]);
  if (estimate->grey_high > estimate->grey_low)
    std::printf("  measured over grey %.0f-%.0f and radii up to %.2f (corner = 1); outside, the curves are continuations\n",
                estimate->grey_low, estimate->grey_high, estimate->radius_high);
  else
    std::printf("  no back-end estimate: the curves are the initial model, not measured\n");
  if (const std::optional<GreyRangeAdvice> advice = online_grey_range_advice(*estimate))
    std::printf("  advice: %s\n", describe(*advice).c_str());
  if (const ReportedExposureScale scale = reported_exposure_scale(exposures.exposure_history()); scale.frames > 0)
    std::printf("  exposures on the reported scale: the estimated chain x %.4f (median over %d frames)\n", scale.factor,
                scale.frames);
  if (errors)
    std::printf("  errors vs ground truth: response %.2f / %.2f grey levels, vignette %.4f / %.4f, exposure %.3f / "
                "%.3f ms (mean / max), relative median %.2f %% / max %.2f %% over %d frames\n",
                errors->response_mean_grey, errors->response_max_grey, errors->vignette_mean, errors->vignette_max,
                errors->exposure_mean_ms, errors->exposure_max_ms, 100.0 * errors->exposure_median_relative,
                100.0 * errors->exposure_max_relative, errors->exposure_frames);
  write_calibration_output(options.out_dir, *estimate, exposures.exposure_history(), info, errors);
  if (!options.json_file.empty()) {
    std::error_code error;
    fs::copy_file(options.out_dir / "calibration.json", options.json_file, fs::copy_options::overwrite_existing, error);
    if (error) throw std::runtime_error(options.json_file.string() + ": cannot write (" + error.message() + ")");
  }
  std::printf("  wrote pcalib.txt, vignette.png, times.txt and calibration.json in %s\n", options.out_dir.string().c_str());
  if (!options.lens_vignette.empty()) write_beam(options.lens_vignette, *estimate, *source, options.out_dir);
  return 0;
}

}  // namespace

void add_calibrate_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<CalibrateOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "calibrate",
      "Online photometric calibration of a whole sequence (response, vignette, per-frame exposure), then a final\n"
      "optimisation over all keyframes. Writes DSO's pcalib.txt, vignette.png, times.txt (estimated exposures,\n"
      "scaled to the reported ones by their median ratio when the source reports them)\n"
      "and calibration.json. With ground truth (a `nirslam simulate` folder or sim:SCENE) also prints the errors.");
  cmd->add_option("sequence", options->source, kSourceArgumentHelp)->required();
  cmd->add_option("--out", options->out_dir, "Output folder")->required();
  cmd->add_option("--max-frames", options->max_frames, "Stop after this many frames")->check(CLI::PositiveNumber);
  cmd->add_option("--json", options->json_file, "Also write calibration.json to this file");
  cmd->add_flag("--ignore-exposures", options->ignore_reported_exposures,
                "Do not use exposure times reported by the source (ambiguity fixed by normalisation instead)");
  cmd->add_option("--lens-vignette", options->lens_vignette,
                  "vignette.png of the lens alone (an earlier calibration with the lamp off): the halo factor\n"
                  "estimated here is split into it and the lamp's beam (beam.png, beam.json: cos^m, half angle)")
      ->check(CLI::ExistingFile);
  cmd->callback([options, &action] { action = [options] { return run_calibrate(*options); }; });
}

}  // namespace nirslam::app
