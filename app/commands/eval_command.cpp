#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "commands/subcommand.hpp"
#include "nirslam/camera/camera_io.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "nirslam/eval/trajectory.hpp"
#include "nirslam/eval/trajectory_plot.hpp"

namespace nirslam::app {
namespace {

namespace fs = std::filesystem;

struct EvalOptions {
  std::string estimate;
  std::string ground_truth;
  std::string align = "sim3";
  std::size_t align_first = 0;
  double max_dt_s = 0.02;
  double time_offset_s = 0.0;
  bool interpolate = false;
  std::size_t rpe_delta = 1;
  double rpe_distance_m = 1.0;
  std::string est_format = "auto";
  std::string gt_format = "auto";
  std::string est_times;
  std::string gt_times;
  double kitti_rate_hz = 0.0;
  std::string gt_sensor_yaml;
  std::string plot;
  std::string plot_size = "1200x900";
  std::string json;
};

bool parse_size(const std::string& text, int& width, int& height) {
  const std::size_t x = text.find('x');
  if (x == std::string::npos) return false;
  try {
    std::size_t used_w = 0, used_h = 0;
    width = std::stoi(text.substr(0, x), &used_w);
    height = std::stoi(text.substr(x + 1), &used_h);
    return used_w == x && used_h == text.size() - x - 1 && width >= 320 && height >= 240 && width <= 8000 &&
           height <= 8000;
  } catch (const std::exception&) {
    return false;
  }
}

Trajectory read_input(const std::string& file, const std::string& format, const std::string& times, double rate_hz) {
  TrajectoryReadOptions options;
  options.format = *trajectory_format_from_string(format);  // checked by CLI::IsMember
  if (!times.empty()) options.kitti.times_file = fs::path(times);
  if (rate_hz > 0.0) options.kitti.rate_hz = rate_hz;
  const Trajectory t = read_trajectory(file, options);
  if (t.format != TrajectoryFormat::Kitti && (!times.empty() || rate_hz > 0.0))
    spdlog::warn("{}: not a KITTI file, its own timestamps are used (times file / rate ignored)", file);
  return t;
}

std::string describe(const Trajectory& t) {
  static const char* names[] = {"auto", "TUM", "KITTI", "EuRoC CSV", "total station"};
  const char* timing = "";
  if (t.format == TrajectoryFormat::Kitti) timing = ", timestamps from times file / rate / frame index";
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, "%s, %zu poses over %.3f s%s%s", names[static_cast<int>(t.format)], t.size(),
                t.poses.back().timestamp_s - t.poses.front().timestamp_s, t.position_only ? ", positions only" : "",
                timing);
  return buffer;
}

void print_row(const char* name, const ErrorStatistics& s) {
  if (s.count == 0) {
    std::printf("  %-28s %10s\n", name, "n/a");
    return;
  }
  std::printf("  %-28s %10.4g %10.4g %10.4g %10.4g %10.4g %10.4g %7zu\n", name, s.rmse, s.mean, s.median, s.std, s.min,
              s.max, s.count);
}

void print_report(const EvalOptions& options, const Trajectory& est, const Trajectory& gt, const EvaluationResult& r) {
  const Association& a = r.association;
  const AlignmentResult& al = r.alignment;
  std::printf("estimate      %s (%s)\n", options.estimate.c_str(), describe(est).c_str());
  std::printf("ground truth  %s (%s)\n", options.ground_truth.c_str(), describe(gt).c_str());
  std::printf("association   %zu of %zu estimated poses paired within %.4g s (%s), max |dt| %.3g ms, %zu unmatched "
              "inside the ground truth's time span\n",
              a.pairs.size(), a.estimate_count, a.options.max_dt_s,
              a.options.method == AssociationMethod::Nearest ? "nearest stamp" : "ground truth interpolated",
              a.max_abs_dt_s * 1e3, a.unmatched_inside_overlap);
  const std::string on = al.pairs_used < a.pairs.size()
                             ? "on the first " + std::to_string(al.pairs_used) + " of " + std::to_string(a.pairs.size()) + " pairs"
                             : "on all " + std::to_string(a.pairs.size()) + " pairs";
  // How far the estimate's scale is off, from the Sim(3) fit on the same pairs (whatever the mode).
  std::string scale_note = "scale error n/a: the positions cannot fix a Sim(3) fit";
  if (const auto error = al.scale_error_percent()) {
    char buffer[160];
    std::snprintf(buffer, sizeof buffer, "the estimate is %.2f %% too %s", std::abs(*error), *error >= 0 ? "large" : "small");
    scale_note = buffer;
  }
  if (al.mode == AlignmentMode::None) {
    std::printf("alignment     none (%s)\n", scale_note.c_str());
  } else if (al.mode == AlignmentMode::Sim3) {
    std::printf("alignment     Sim(3) %s, scale %.6g (%s)\n", on.c_str(), al.transform.scale, scale_note.c_str());
  } else {
    std::printf("alignment     SE(3) %s, scale fixed at 1 (a Sim(3) fit would scale by %.6g: %s)\n", on.c_str(),
                al.sim3_scale.value_or(1.0), scale_note.c_str());
  }
  std::printf("ground-truth path length over the pairs: %.3f m\n\n", r.ground_truth_path_length_m);

  std::printf("  %-28s %10s %10s %10s %10s %10s %10s %7s\n", "measure", "rmse", "mean", "median", "std", "min", "max",
              "count");
  print_row("ATE [m]", r.ate_m);
  const std::string frame = "RPE " + std::to_string(static_cast<int>(r.rpe_per_frame.delta)) + " frame";
  print_row((frame + " trans [m]").c_str(), r.rpe_per_frame.translation_m);
  if (r.rpe_per_frame.has_rotation) print_row((frame + " rot [deg]").c_str(), r.rpe_per_frame.rotation_deg);
  if (r.rpe_per_distance) {
    const RelativeError& d = *r.rpe_per_distance;
    char metres[32];
    std::snprintf(metres, sizeof metres, "RPE %g m", d.delta);
    const std::string m = metres;
    if (d.translation_m.count == 0) {
      std::printf("  %-28s %10s (the ground-truth path is shorter than %g m)\n", (m + " segments").c_str(), "n/a", d.delta);
    } else {
      print_row((m + " trans [m]").c_str(), d.translation_m);
      print_row((m + " trans [%]").c_str(), d.translation_percent);
      if (d.has_rotation) {
        print_row((m + " rot [deg]").c_str(), d.rotation_deg);
        print_row((m + " rot [deg/m]").c_str(), d.rotation_deg_per_m);
      }
    }
  }
  if (r.position_only) std::printf("\n(position-only input: rotation errors do not apply)\n");
}

int run_eval(const EvalOptions& options) {
  Trajectory est = read_input(options.estimate, options.est_format, options.est_times, options.kitti_rate_hz);
  Trajectory gt = read_input(options.ground_truth, options.gt_format, options.gt_times, options.kitti_rate_hz);
  if (!options.gt_sensor_yaml.empty()) {
    if (gt.position_only)
      throw InputError(options.ground_truth, "is position-only: --gt-sensor needs orientations to apply T_BS");
    const EurocCameraSensor sensor = read_euroc_sensor_yaml(options.gt_sensor_yaml);
    const SE3 T_body_cam(Eigen::Matrix3d(sensor.T_body_sensor.topLeftCorner<3, 3>()),
                         Eigen::Vector3d(sensor.T_body_sensor.topRightCorner<3, 1>()));
    gt = transform_body_to_camera(gt, T_body_cam);
  }

  EvaluationOptions eval;
  eval.alignment = *alignment_mode_from_string(options.align);  // checked by CLI::IsMember
  eval.align_first = options.align_first;
  eval.association.max_dt_s = options.max_dt_s;
  eval.association.time_offset_s = options.time_offset_s;
  eval.association.method = options.interpolate ? AssociationMethod::Interpolate : AssociationMethod::Nearest;
  eval.rpe_delta_frames = options.rpe_delta;
  eval.rpe_distance_m = options.rpe_distance_m;
  const EvaluationResult result = evaluate(est, gt, eval);

  print_report(options, est, gt, result);

  if (!options.json.empty()) {
    std::ofstream out(options.json);
    out << evaluation_to_json(result) << '\n';
    out.flush();
    if (!out) throw InputError(options.json, "cannot write the JSON report");
    std::printf("\nWrote %s\n", options.json.c_str());
  }
  if (!options.plot.empty()) {
    ErrorPlotOptions plot;
    parse_size(options.plot_size, plot.width, plot.height);  // checked by the option's validator
    write_png(options.plot, render_evaluation_heat_map(gt.positions(), result, plot));
    std::printf("%sWrote %s (%dx%d heat map of the per-pose ATE)\n", options.json.empty() ? "\n" : "",
                options.plot.c_str(), plot.width, plot.height);
  }
  return 0;
}

}  // namespace

void add_eval_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<EvalOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "eval",
      "Compare an estimated trajectory with ground truth: timestamp association, Umeyama alignment, ATE and RPE, "
      "optionally a top-view heat map of the per-pose error (PNG) and a JSON report");
  const std::string formats = "auto, tum, kitti, euroc, total-station";
  cmd->add_option("estimate", options->estimate, "Estimated trajectory (TUM, KITTI, EuRoC CSV or 'timestamp x y z')")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("ground_truth", options->ground_truth, "Ground-truth trajectory (same formats)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--align", options->align, "Alignment before the ATE: sim3 (monocular), se3, none")
      ->capture_default_str()
      ->check(CLI::IsMember({"sim3", "se3", "none"}));
  cmd->add_option("--align-first", options->align_first, "Align on the first N matched pairs only (0: all)")
      ->capture_default_str();
  cmd->add_option("--max-dt", options->max_dt_s, "Association tolerance in seconds")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--interpolate", options->interpolate,
                "Interpolate the ground truth at the estimated timestamps (dense ground truth) instead of taking "
                "the nearest stamp");
  cmd->add_option("--time-offset", options->time_offset_s, "Seconds added to the estimated timestamps")
      ->capture_default_str();
  cmd->add_option("--rpe-delta", options->rpe_delta, "Frame step of the per-frame RPE")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--rpe-distance", options->rpe_distance_m, "Path length in metres of the per-distance RPE (0: off)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--est-format", options->est_format, "Format of the estimate: " + formats)
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "tum", "kitti", "euroc", "total-station"}));
  cmd->add_option("--gt-format", options->gt_format, "Format of the ground truth: " + formats)
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "tum", "kitti", "euroc", "total-station"}));
  cmd->add_option("--est-times", options->est_times, "Timestamps of a KITTI estimate (times.txt)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--gt-times", options->gt_times, "Timestamps of a KITTI ground truth (times.txt)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--kitti-rate", options->kitti_rate_hz,
                  "Frame rate in Hz giving KITTI poses timestamps when there is no times file (default: frame "
                  "index as seconds)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--gt-sensor", options->gt_sensor_yaml,
                  "EuRoC sensor.yaml whose T_BS turns body ground truth into camera poses (pose * T_BS)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--plot", options->plot, "Write the trajectory error heat map (top view) to this PNG");
  cmd->add_option("--plot-size", options->plot_size, "Heat map size in pixels, WIDTHxHEIGHT")
      ->capture_default_str()
      ->check([](const std::string& text) {
        int width = 0, height = 0;
        return parse_size(text, width, height) ? std::string()
                                               : std::string("expected WIDTHxHEIGHT between 320x240 and 8000x8000");
      });
  cmd->add_option("--json", options->json, "Write every figure as JSON to this file");
  cmd->callback([options, &action] { action = [options] { return run_eval(*options); }; });
}

}  // namespace nirslam::app
