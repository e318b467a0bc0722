#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/source_argument.hpp"
#include "commands/subcommand.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "nirslam/photometric/calibration_output.hpp"
#include "nirslam/session/metrics_csv_writer.hpp"
#include "nirslam/session/odometry_output.hpp"
#include "nirslam/sources/frame_limit.hpp"
#include "nirslam/sources/read_ahead.hpp"
#include "nirslam/worker/worker.hpp"

namespace nirslam::app {
namespace {

struct RunOptions {
  std::string source = kDefaultSource;
  std::filesystem::path out_dir = "nirslam-run";
  std::string mode;  // empty: the configured one
  bool recorded_speed = false;
  std::int64_t max_frames = 0;
  double progress_interval_s = 1.0;
  std::filesystem::path given_calibration;  // empty: the configured one (calibration.given), else online
  bool online_calibration = false;          // leave out the configured given calibration
};

double peak_memory_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

// What the worker thread gathers while the run goes (read here only after the run settled).
struct RunTotals {
  double entropy_sum = 0.0;
  double photometric_ms = 0.0;
  double odometry_ms = 0.0;
  double mapping_ms = 0.0;
  double quality_ms = 0.0;
  double read_ms = 0.0;
  std::int64_t frames = 0;
  std::int64_t keyframes = 0;
  std::int64_t lost_frames = 0;
  std::string source_kind;
  int width = 0;   // of the frames
  int height = 0;
  Trajectory ground_truth;  // from frames that carry it (simulator)
  // From the finish handler.
  std::int64_t poses = 0;
  int segments = 0;
  std::int64_t map_points = 0;
  std::vector<std::string> files;
  nlohmann::json light_offset;  // the lamp offset estimate (illuminated mode), null without one
};

void write_summary(const std::filesystem::path& file, const RunOptions& options, const PipelineOptions& pipeline,
                   const Snapshot& last, double wall_s, const RunTotals& totals) {
  const PipelineMode mode = pipeline.mode;
  // Where the corrected frames' model came from: estimated online, or given as files.
  const nlohmann::json photometric_calibration =
      !runs_calibration(mode)                     ? nlohmann::json(nullptr)
      : pipeline.given_calibration_folder.empty()
          ? nlohmann::json("online")
          : nlohmann::json({{"folder", pipeline.given_calibration_folder.string()},
                            {"held", to_string(pipeline.given_calibration_holds)}});
  const double n = totals.frames > 0 ? static_cast<double>(totals.frames) : 1.0;
  nlohmann::json summary = {
      {"nirslam_version", NIRSLAM_VERSION},
      {"source", {{"argument", options.source}, {"kind", last.source.kind}, {"description", last.source.description}}},
      {"mode", std::string(to_string(mode))},
      {"photometric_calibration", photometric_calibration},
      // Which configuration made these figures: the --config file, else the shipped one.
      {"config_file", app_config_file().empty() ? nlohmann::json(nullptr) : nlohmann::json(app_config_file().string())},
      {"state", to_string(last.state)},
      {"message", last.message},
      {"frames_processed", last.frames_processed},
      {"frames_dropped", last.frames_dropped},
      {"wall_time_s", wall_s},
      {"frames_per_second", wall_s > 0 ? last.frames_processed / wall_s : 0.0},
      {"peak_memory_mib", peak_memory_mib()},
      {"mean_entropy_bits", totals.entropy_sum / n},
      {"mean_ms", {{"read", totals.read_ms / n}, {"quality", totals.quality_ms / n},
                   {"photometric", totals.photometric_ms / n}, {"odometry", totals.odometry_ms / n},
                   {"mapping", totals.mapping_ms / n}}},
      {"odometry", {{"poses", totals.poses}, {"keyframes", totals.keyframes}, {"segments", totals.segments},
                    {"lost_frames", totals.lost_frames}, {"map_points", totals.map_points}}},
      {"light_offset_estimate", totals.light_offset},
      {"files", totals.files},
  };
  std::ofstream out(file);
  out << summary.dump(2) << '\n';
  if (!out) throw std::runtime_error(file.string() + ": cannot write the run summary");
}

// Writes what the pipeline ended with: trajectory, keyframes, points, calibration.
void write_pipeline_outputs(const SlamPipeline& pipeline, const std::filesystem::path& out_dir, RunTotals& totals) {
  if (const auto& e = pipeline.light_offset_estimate()) {
    const Eigen::Vector3d sigma = e->sigma();
    totals.light_offset = {{"offset_cam", {e->offset_cam.x(), e->offset_cam.y(), e->offset_cam.z()}},
                           {"sigma", {sigma.x(), sigma.y(), sigma.z()}},
                           {"determined", e->determined},
                           {"reason", e->reason},
                           {"points", e->points},
                           {"median_point_distance", e->median_distance},
                           {"rms_log_before", e->rms_log_before},
                           {"rms_log_after", e->rms_log_after},
                           {"applied", pipeline.options().apply_estimated_light_offset && e->determined}};
  }
  if (const DirectOdometry* odometry = pipeline.odometry()) {
    const std::vector<PoseStamped> trajectory = odometry->trajectory();
    const std::vector<MapPoint> points = odometry->points();
    write_trajectory_tum(out_dir / "trajectory.txt", trajectory);
    write_keyframes(out_dir / "keyframes.txt", odometry->keyframes());
    write_points_ply(out_dir / "points.ply", points);
    totals.poses = static_cast<std::int64_t>(trajectory.size());
    totals.segments = trajectory.empty() ? 0 : trajectory.back().segment + 1;
    totals.map_points = static_cast<std::int64_t>(points.size());
    totals.files.insert(totals.files.end(), {"trajectory.txt", "keyframes.txt", "points.ply"});
  }
  if (const OnlinePhotometricCalibration* calibration = pipeline.calibration()) {
    CalibrationOutputInfo info;
    info.source = totals.source_kind;
    info.width = totals.width;
    info.height = totals.height;
    info.frames = totals.frames;
    info.mean_front_end_ms = totals.frames > 0 ? totals.photometric_ms / static_cast<double>(totals.frames) : 0.0;
    write_calibration_output(out_dir / "calibration", *calibration->estimate(), calibration->exposure_history(), info,
                             std::nullopt);
    totals.files.push_back("calibration/");
  }
}

int run_headless(const RunOptions& options) {
  SourceFactory factory = source_factory_from_argument(options.source);
  if (options.max_frames > 0)
    factory = [factory, n = options.max_frames] { return limit_frames(factory(), n); };
  // Decoding the next frames overlaps the pipeline (the worker's read time is then the wait).
  factory = [factory] { return read_ahead(factory()); };

  std::error_code error;
  std::filesystem::create_directories(options.out_dir, error);
  if (error) throw std::runtime_error(options.out_dir.string() + ": cannot create output folder (" + error.message() + ")");

  WorkerOptions worker_options = app_config().worker;
  if (options.recorded_speed) worker_options.pacing = Pacing::RecordedSpeed;
  if (options.mode == "auto") {
    worker_options.pipeline_mode_automatic = true;
  } else if (!options.mode.empty()) {
    const auto mode = parse_pipeline_mode(options.mode);
    if (!mode)
      throw std::invalid_argument(
          "--mode: expected auto, quality, odometry, calibrated, illuminated or odometry-illuminated, got '" +
          options.mode + "'");
    worker_options.pipeline.mode = *mode;
    worker_options.pipeline_mode_automatic = false;
  }
  if (options.online_calibration && !options.given_calibration.empty())
    throw std::invalid_argument("--online-calibration and --photometric-calibration: give one of the two");
  if (options.online_calibration) {
    worker_options.pipeline.given_calibration_folder.clear();
    worker_options.pipeline.given_calibration_holds = GivenCalibrationParts::Both;
    worker_options.pipeline.estimate_beam = false;
    worker_options.pipeline.beam_in_odometry = false;
  }
  if (!options.given_calibration.empty()) {
    if (!std::filesystem::is_directory(options.given_calibration))
      throw InputError(options.given_calibration, "--photometric-calibration: not a folder (one holding pcalib.txt and vignette.png)");
    worker_options.pipeline.given_calibration_folder = options.given_calibration;
  }

  auto csv = std::make_shared<MetricsCsvWriter>(options.out_dir / "quality.csv");
  RunTotals totals;  // written by the worker thread, read here once it has settled
  totals.files.push_back("quality.csv");
  Worker worker(worker_options);
  worker.set_observer([csv, &totals](const Snapshot& s) {
    csv->write(s);
    totals.entropy_sum += s.quality.entropy_bits;
    totals.read_ms += s.timings.read_ms;
    totals.quality_ms += s.timings.quality_ms;
    totals.photometric_ms += s.timings.photometric_ms;
    totals.odometry_ms += s.timings.odometry_ms;
    totals.mapping_ms += s.timings.mapping_ms;
    totals.keyframes += s.stages.keyframe ? 1 : 0;
    totals.lost_frames += s.stages.tracking == "lost" ? 1 : 0;
    ++totals.frames;
    if (s.frame) {
      totals.width = s.frame->width();
      totals.height = s.frame->height();
    }
    if (s.frame && s.frame->T_world_cam_truth)
      totals.ground_truth.poses.push_back({s.frame->timestamp_s, *s.frame->T_world_cam_truth});
  });
  const std::filesystem::path out_dir = options.out_dir;
  worker.set_finish_handler([&totals, out_dir](const SlamPipeline& pipeline) {
    write_pipeline_outputs(pipeline, out_dir, totals);
  });
  worker.post(command::SetSource{factory});
  worker.post(command::Start{});

  const auto started = std::chrono::steady_clock::now();
  const auto interval = std::chrono::milliseconds(static_cast<int>(options.progress_interval_s * 1000));
  std::shared_ptr<const Snapshot> last = worker.snapshot();
  while (!settled(*last)) {
    last = worker.wait_for(settled, interval);
    if (last->frame && !settled(*last)) {
      const auto total = last->source.frame_count;
      const std::string tracking = last->trajectory && last->trajectory->enabled ? " | " + last->trajectory->tracking : "";
      spdlog::info("frame {}{} | entropy {:.3f} bit | {:.1f} fps{}", last->frames_processed,
                   total ? "/" + std::to_string(*total) : std::string(), last->quality.entropy_bits,
                   last->processing_fps, tracking);
    }
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  // Every observer and finish-handler call happened on the worker thread before the settled
  // snapshot was published, and loading that snapshot orders them before the reads below.
  totals.source_kind = last->source.kind;
  // The automatic mode was chosen for the source on the worker thread: the snapshot names it.
  PipelineOptions pipeline_used = worker_options.pipeline;
  if (const auto resolved = parse_pipeline_mode(last->pipeline_mode)) pipeline_used.mode = *resolved;
  const PipelineMode mode = pipeline_used.mode;
  if (!totals.ground_truth.empty()) {
    write_tum(options.out_dir / "groundtruth.txt", totals.ground_truth);
    totals.files.push_back("groundtruth.txt");
  }
  write_summary(options.out_dir / "summary.json", options, pipeline_used, *last, wall_s, totals);

  if (!last->pipeline_error.empty()) {
    // The stages the mode asks for never ran: not a result to hand on.
    spdlog::error("{}", last->pipeline_error);
    std::printf("Only image quality was computed (%lld frames, in %s): %s\n", static_cast<long long>(csv->rows()),
                options.out_dir.string().c_str(), last->pipeline_error.c_str());
    return 1;
  }
  if (last->state == WorkerState::Failed) {
    spdlog::error("stopped after {} frames: {}", last->frames_processed, last->message);
    std::printf("Partial results (%lld frames) in %s\n", static_cast<long long>(csv->rows()),
                options.out_dir.string().c_str());
    return 1;
  }
  const double n = totals.frames > 0 ? static_cast<double>(totals.frames) : 1.0;
  std::printf("Processed %lld frames in %.2f s (%.1f fps), mode %s, mean entropy %.3f bit\n",
              static_cast<long long>(last->frames_processed), wall_s, wall_s > 0 ? last->frames_processed / wall_s : 0.0,
              std::string(to_string(mode)).c_str(), totals.entropy_sum / n);
  std::printf("Per frame: read %.2f ms, quality %.2f ms, photometric %.2f ms, odometry %.2f ms (mapping %.2f ms); peak memory %.0f MiB\n",
              totals.read_ms / n, totals.quality_ms / n, totals.photometric_ms / n, totals.odometry_ms / n,
              totals.mapping_ms / n, peak_memory_mib());
  if (totals.poses > 0 || mode != PipelineMode::Quality)
    std::printf("Odometry: %lld poses, %lld keyframes, %d segment(s), %lld frames lost, %lld map points\n",
                static_cast<long long>(totals.poses), static_cast<long long>(totals.keyframes), totals.segments,
                static_cast<long long>(totals.lost_frames), static_cast<long long>(totals.map_points));
  std::string files;
  for (const std::string& f : totals.files) files += (files.empty() ? "" : ", ") + f;
  std::printf("Wrote %s and summary.json in %s\n", files.c_str(), options.out_dir.string().c_str());
  return 0;
}

}  // namespace

void add_run_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "run", "Process a sequence without the GUI: per-frame image quality (quality.csv), the camera path "
             "(trajectory.txt, keyframes.txt), the map (points.ply), the photometric calibration (calibration/) "
             "and summary.json");
  cmd->add_option("source", options->source, kSourceArgumentHelp)->capture_default_str();
  cmd->add_option("-o,--out", options->out_dir, "Output folder (created when missing)")->capture_default_str();
  cmd->add_option("--mode", options->mode,
                  "Pipeline stages: quality (metrics only), odometry (plain direct odometry), calibrated "
                  "(online photometric calibration + odometry), illuminated (calibrated + the co-located lamp's "
                  "distance and power factor), odometry-illuminated (odometry + the lamp's factor, no calibration), "
                  "auto (illuminated when the source reports its lamp's power, else calibrated); "
                  "default from the config (pipeline.mode)")
      ->check(CLI::IsMember({"auto", "quality", "odometry", "calibrated", "illuminated", "odometry-illuminated"}));
  cmd->add_flag("--realtime", options->recorded_speed,
                "Follow the recorded timestamps instead of running flat out (config: worker.pacing)");
  cmd->add_option("--max-frames", options->max_frames, "Stop after this many frames")->check(CLI::PositiveNumber);
  cmd->add_option("--photometric-calibration", options->given_calibration,
                  "Folder with DSO's pcalib.txt (and vignette.png), e.g. a TUM monoVO dataset or `nirslam calibrate`'s "
                  "output: the modes with calibration hold it instead of estimating it online (config: calibration.given)");
  cmd->add_flag("--online-calibration", options->online_calibration,
                "Estimate the whole photometric calibration online: leave out the config's calibration.given, "
                "given_holds, estimate_beam and beam_in_odometry (bench's modes outside --given-calibration-modes)");
  cmd->callback([options, &action] { action = [options] { return run_headless(*options); }; });
}

}  // namespace nirslam::app
