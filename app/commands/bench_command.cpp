// `nirslam bench`: the accuracy table of the paper's Table 2, made reproducible. Simulated
// sequences (four scenes x illuminator powers) are rendered once into a cache, every sequence is
// processed by `nirslam run` in each pipeline mode (a child process per run, so its peak memory
// is its own), and the trajectories are evaluated against the ground truth (ATE after Sim(3)).

#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/subcommand.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/eval/benchmark_table.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "nirslam/pipeline/slam_pipeline.hpp"
#include "nirslam/session/odometry_output.hpp"
#include "nirslam/sim/sequence_writer.hpp"

extern char** environ;

namespace nirslam::app {
namespace {

namespace fs = std::filesystem;

struct BenchOptions {
  std::vector<std::string> datasets;
  std::vector<std::string> scenes{"room", "outdoor", "parking", "tunnel"};
  std::vector<double> powers{20.0, 50.0, 100.0};
  std::vector<std::string> modes;  // empty: every odometry mode, in order
  std::int64_t frames = 300;
  std::string size = "640x480";
  fs::path out_dir = "nirslam-bench";
  bool no_simulated = false;
  bool dataset_calibration = false;  // each sequence's own pcalib.txt / vignette.png, held
  fs::path given_calibration;        // or one folder for every sequence (the rig's, e.g. lamp off)
  std::vector<std::string> given_calibration_modes;  // empty: every mode that runs the calibration
};

struct BenchSequence {
  std::string name;   // "Room_20"
  fs::path folder;
  std::optional<fs::path> ground_truth;
};

// The paper's row names: Room, Outside, Parking, Tunnel.
std::string row_name(const std::string& scene, double power) {
  std::string name = scene == "outdoor" ? "Outside" : scene;
  name[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(name[0])));
  return fmt::format("{}_{:g}", name, power);
}

sim::MotionKind motion_for(sim::SceneKind scene) {
  // As the scenes are captured: on foot indoors and in the tunnel, from a vehicle outside.
  return scene == sim::SceneKind::Outdoor || scene == sim::SceneKind::Parking ? sim::MotionKind::Vehicle
                                                                             : sim::MotionKind::Handheld;
}

std::pair<int, int> parse_size(const std::string& size) {
  int w = 0;
  int h = 0;
  char x = 0;
  std::istringstream in(size);
  if (!(in >> w >> x >> h) || x != 'x' || w < 64 || h < 48)
    throw std::invalid_argument("--size: expected WIDTHxHEIGHT (at least 64x48), got '" + size + "'");
  return {w, h};
}

// Renders a simulated sequence unless the cache has it already (same options, complete).
BenchSequence simulated_sequence(const BenchOptions& o, const std::string& scene_name, double power) {
  const auto scene = sim::parse_scene_kind(scene_name);
  if (!scene) throw std::invalid_argument("--scenes: unknown scene '" + scene_name + "' (room, outdoor, parking, tunnel)");
  const auto [width, height] = parse_size(o.size);
  SimulatorOptions s;
  s.scene = *scene;
  s.motion = motion_for(*scene);
  s.powers_w = {power};
  s.frames = o.frames;
  s.width = width;
  s.height = height;
  validate(s);
  BenchSequence sequence;
  sequence.name = row_name(scene_name, power);
  sequence.folder = o.out_dir / "sequences" / fmt::format("{}_{}f_{}", sequence.name, o.frames, o.size);
  sequence.ground_truth = sequence.folder / "groundtruth.txt";
  const fs::path done = sequence.folder / ".complete";
  if (!fs::exists(done)) {
    std::printf("rendering %s (%lld frames, %s)...\n", sequence.name.c_str(), static_cast<long long>(o.frames), o.size.c_str());
    std::fflush(stdout);
    fs::remove_all(sequence.folder);
    write_simulated_sequence(s, sequence.folder);
    std::ofstream(done) << "complete\n";
  }
  return sequence;
}

BenchSequence dataset_sequence(const std::string& argument) {
  const fs::path folder(argument);
  if (!fs::exists(folder)) throw InputError(folder, "no such dataset folder");
  BenchSequence sequence;
  sequence.name = folder.filename().empty() ? folder.parent_path().filename().string() : folder.filename().string();
  sequence.folder = folder;
  for (const char* candidate : {"groundtruth.txt", "groundtruth_tum.txt"})
    if (fs::exists(folder / candidate)) {
      sequence.ground_truth = folder / candidate;
      break;
    }
  return sequence;
}

struct ChildResult {
  int exit_code = -1;
  double peak_memory_mib = 0.0;
  double wall_s = 0.0;
};

// Runs this executable with `arguments`, output to `log`; waits and reads its peak memory.
ChildResult run_child(const std::vector<std::string>& arguments, const fs::path& log) {
  std::vector<std::string> argv_storage{fs::read_symlink("/proc/self/exe").string()};
  argv_storage.insert(argv_storage.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (std::string& a : argv_storage) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  pid_t pid = 0;
  const auto started = std::chrono::steady_clock::now();
  const int spawned = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) throw std::runtime_error(fmt::format("cannot start {}: {}", argv[0], std::strerror(spawned)));
  int status = 0;
  rusage usage{};
  if (wait4(pid, &status, 0, &usage) < 0) throw std::runtime_error(fmt::format("waiting for the run: {}", std::strerror(errno)));
  ChildResult result;
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  result.peak_memory_mib = static_cast<double>(usage.ru_maxrss) / 1024.0;
  return result;
}

// Evaluates a run's trajectory: the whole of it when it tracked throughout, else its longest
// segment (each segment has its own scale and origin), and says so.
void evaluate_run(const BenchSequence& sequence, const fs::path& run_dir, std::int64_t frames, BenchmarkRun& run) {
  const fs::path trajectory_file = run_dir / "trajectory.txt";
  if (!fs::exists(trajectory_file)) {
    run.note = "no trajectory";
    return;
  }
  const std::vector<Trajectory> segments = read_trajectory_segments(trajectory_file);
  run.segments = static_cast<int>(segments.size());
  if (segments.empty()) {
    run.note = "no pose";
    return;
  }
  const auto longest = std::max_element(segments.begin(), segments.end(),
                                        [](const Trajectory& a, const Trajectory& b) { return a.size() < b.size(); });
  run.tracked_fraction = frames > 0 ? static_cast<double>(longest->size()) / static_cast<double>(frames) : 0.0;
  if (!sequence.ground_truth) {
    run.note = "no ground truth";
    return;
  }
  try {
    const Trajectory truth = read_trajectory(*sequence.ground_truth);
    const EvaluationResult result = evaluate(*longest, truth);
    run.ate_rmse_m = result.ate_m.rmse;
    run.path_length_m = result.ground_truth_path_length_m;
  } catch (const std::exception& e) {
    // The whole message goes to the progress line; the table cell keeps its gist.
    std::string message = e.what();
    const std::string prefix = trajectory_file.string() + ": ";
    if (message.rfind(prefix, 0) == 0) message.erase(0, prefix.size());
    std::fprintf(stderr, "\n  %s: %s\n", sequence.name.c_str(), e.what());
    run.note = message.size() > 48 ? message.substr(0, 45) + "..." : message;
  }
}

// What a run's summary.json says; zeros when it is missing or unreadable (the run failed, and
// its exit code says so).
struct RunSummary {
  std::int64_t frames = 0;
  double frames_per_second = 0.0;
  int keyframes = 0;
};

RunSummary summary_of(const fs::path& run_dir) {
  RunSummary summary;
  std::ifstream in(run_dir / "summary.json");
  if (!in) return summary;
  try {
    const nlohmann::json json = nlohmann::json::parse(in);
    summary.frames = json.value("frames_processed", std::int64_t{0});
    summary.frames_per_second = json.value("frames_per_second", 0.0);
    if (const auto odometry = json.find("odometry"); odometry != json.end() && odometry->is_object())
      summary.keyframes = odometry->value("keyframes", 0);
  } catch (const std::exception&) {
    return {};
  }
  return summary;
}

// bench.md's first line when a calibration is given: which files, which part held, in which modes.
std::string given_calibration_header(const BenchOptions& o, const std::vector<std::string>& given_modes) {
  if (!o.dataset_calibration && o.given_calibration.empty()) return {};
  const GivenCalibrationParts held = app_config().worker.pipeline.given_calibration_holds;
  const std::string read = held == GivenCalibrationParts::Response ? "pcalib.txt"
                           : held == GivenCalibrationParts::Vignette ? "vignette.png"
                                                                     : "pcalib.txt and vignette.png";
  const std::string files = o.dataset_calibration ? "each sequence's own " + read
                                                  : "the " + read + " of " + o.given_calibration.string();
  const std::string part = held == GivenCalibrationParts::Both ? std::string("both held, nothing estimated online")
                           : held == GivenCalibrationParts::Response
                               ? std::string(app_config().worker.pipeline.lamp_halo == LampHaloModel::Beam
                                                 ? "the response (pcalib.txt) held, the halo factor estimated online "
                                                   "(in the illuminated mode as the lamp's beam over a flat lens)"
                                                 : "the response (pcalib.txt) held, the halo factor estimated online")
                               : fmt::format("the lens vignette (vignette.png) held, the lamp's beam (exponent {}{}) {}, "
                                             "the response estimated online",
                                             app_config().worker.pipeline.odometry.beam_exponent,
                                             app_config().worker.pipeline.estimate_beam ? ", refined online" : ", configured",
                                             app_config().worker.pipeline.beam_in_odometry
                                                 ? "in the odometry's lamp factor"
                                                 : "in the halo factor the frames are corrected with");
  return fmt::format("Photometric calibration given (run --photometric-calibration) in mode{} {}: {}; {} "
                     "(calibration.given_holds: {}). Other modes estimate it online.\n\n",
                     given_modes.size() == 1 ? "" : "s", fmt::join(given_modes, ", "), files, part, to_string(held));
}

int run_bench(const BenchOptions& o) {
  std::vector<std::string> modes = o.modes;
  if (modes.empty())
    for (PipelineMode m : odometry_modes()) modes.emplace_back(to_string(m));
  for (const std::string& m : modes)
    if (!parse_pipeline_mode(m) || *parse_pipeline_mode(m) == PipelineMode::Quality)
      throw std::invalid_argument("--modes: '" + m +
                                  "' is not an odometry mode (odometry, calibrated, illuminated, odometry-illuminated)");
  if (o.dataset_calibration && !o.given_calibration.empty())
    throw std::invalid_argument("--dataset-calibration and --photometric-calibration: give one of the two");
  if (!o.given_calibration.empty() && !fs::is_directory(o.given_calibration))
    throw InputError(o.given_calibration, "--photometric-calibration: not a folder (one holding pcalib.txt and vignette.png)");
  const bool holds_given = o.dataset_calibration || !o.given_calibration.empty();
  std::vector<std::string> given_modes = o.given_calibration_modes;
  if (!holds_given && !given_modes.empty())
    throw std::invalid_argument("--given-calibration-modes: needs --dataset-calibration or --photometric-calibration");
  if (given_modes.empty())
    for (const std::string& m : modes)
      if (runs_calibration(*parse_pipeline_mode(m))) given_modes.push_back(m);
  for (const std::string& m : given_modes) {
    const auto mode = parse_pipeline_mode(m);
    if (!mode || !runs_calibration(*mode) || std::find(modes.begin(), modes.end(), m) == modes.end())
      throw std::invalid_argument("--given-calibration-modes: '" + m +
                                  "' is not one of the --modes that run the photometric calibration");
  }
  const auto holds_given_in = [&](const std::string& mode) {
    return holds_given && std::find(given_modes.begin(), given_modes.end(), mode) != given_modes.end();
  };
  fs::create_directories(o.out_dir);

  std::vector<BenchSequence> sequences;
  if (!o.no_simulated)
    for (const std::string& scene : o.scenes)
      for (double power : o.powers) sequences.push_back(simulated_sequence(o, scene, power));
  for (const std::string& dataset : o.datasets) sequences.push_back(dataset_sequence(dataset));
  if (sequences.empty()) throw std::invalid_argument("nothing to run: give dataset folders or leave out --no-simulated");

  BenchmarkTable table;
  table.modes = modes;
  const std::size_t total = sequences.size() * modes.size();
  std::size_t done = 0;
  bool all_ok = true;
  for (const BenchSequence& sequence : sequences) {
    table.sequences.push_back(sequence.name);
    for (const std::string& mode : modes) {
      ++done;
      const fs::path run_dir = o.out_dir / "runs" / sequence.name / mode;
      fs::create_directories(run_dir);
      std::printf("[%zu/%zu] %-12s %-11s ", done, total, sequence.name.c_str(), mode.c_str());
      std::fflush(stdout);
      std::vector<std::string> arguments;
      if (!app_config_file().empty()) arguments = {"--config", app_config_file().string()};  // the runs use bench's own
      arguments.insert(arguments.end(), {"run", sequence.folder.string(), "--mode", mode, "--out", run_dir.string()});
      if (holds_given_in(mode))
        arguments.insert(arguments.end(), {"--photometric-calibration",
                                           (o.dataset_calibration ? sequence.folder : o.given_calibration).string()});
      else if (holds_given && runs_calibration(*parse_pipeline_mode(mode)))
        arguments.emplace_back("--online-calibration");
      const ChildResult child = run_child(arguments, run_dir / "run.log");
      BenchmarkRun run;
      run.sequence = sequence.name;
      run.mode = mode;
      run.peak_memory_mib = child.peak_memory_mib;
      const RunSummary summary = summary_of(run_dir);
      run.frames_per_second = summary.frames_per_second;
      run.keyframes = summary.keyframes;
      if (child.exit_code != 0) {
        run.note = fmt::format("run failed (exit {}), see {}", child.exit_code, (run_dir / "run.log").string());
        all_ok = false;
      } else {
        evaluate_run(sequence, run_dir, summary.frames, run);
      }
      std::printf("%s | %.1f fps | %.0f MiB | %.0f s%s%s\n",
                  run.ate_rmse_m ? fmt::format("ATE {:.4f} m ({:.2f} % of {:.1f} m)", *run.ate_rmse_m,
                                               run.ate_percent_of_path().value_or(0.0), run.path_length_m)
                                       .c_str()
                                 : ("no ATE: " + run.note).c_str(),
                  run.frames_per_second, run.peak_memory_mib, child.wall_s,
                  run.keyframes > 0 ? fmt::format(" | {} keyframes", run.keyframes).c_str() : "",
                  run.segments > 1 ? fmt::format(" | {} segments", run.segments).c_str() : "");
      std::fflush(stdout);
      table.runs.push_back(std::move(run));
    }
  }

  const std::string markdown = given_calibration_header(o, given_modes) + benchmark_markdown(table);
  {
    std::ofstream md(o.out_dir / "bench.md", std::ios::trunc);
    md << markdown;
    if (!md) throw std::runtime_error((o.out_dir / "bench.md").string() + ": cannot write");
  }
  write_benchmark_csv(o.out_dir / "bench.csv", table);
  std::printf("\n%s\nWrote %s and %s\n", markdown.c_str(), (o.out_dir / "bench.md").string().c_str(),
              (o.out_dir / "bench.csv").string().c_str());
  return all_ok ? 0 : 1;
}

}  // namespace

void add_bench_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<BenchOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "bench", "Run the accuracy benchmark: simulated sequences (scenes x illuminator powers) and any dataset folders "
               "through `run` in each pipeline mode; writes bench.md and bench.csv (the paper's Table 2 layout)");
  cmd->add_option("datasets", options->datasets, "Extra dataset folders (ATE when they hold groundtruth.txt)");
  cmd->add_option("--scenes", options->scenes, "Simulated scenes, comma-separated (room, outdoor, parking, tunnel)")->delimiter(',')->capture_default_str();
  cmd->add_option("--powers", options->powers, "Illuminator powers in watts, comma-separated")->delimiter(',')->capture_default_str();
  cmd->add_option("--modes", options->modes, "Pipeline modes to compare, in order (default: odometry,calibrated,illuminated)")
      ->delimiter(',');
  cmd->add_option("--frames", options->frames, "Frames per simulated sequence")->check(CLI::Range(10, 100000))->capture_default_str();
  cmd->add_option("--size", options->size, "Size of the simulated frames, WIDTHxHEIGHT")->capture_default_str();
  cmd->add_flag("--no-simulated", options->no_simulated, "Only the dataset folders given");
  cmd->add_flag("--dataset-calibration", options->dataset_calibration,
                "The calibrated modes hold each sequence's own pcalib.txt and vignette.png (a TUM monoVO folder's; "
                "simulated sequences carry the true ones) instead of estimating them online; the config's "
                "calibration.given_holds may hold one of the two and estimate the other");
  cmd->add_option("--photometric-calibration", options->given_calibration,
                  "One calibration folder (pcalib.txt, vignette.png; e.g. `calibrate` of a lamp-off sequence of the same "
                  "camera) held in the calibrated modes of every sequence, as calibration.given_holds says");
  cmd->add_option("--given-calibration-modes", options->given_calibration_modes,
                  "Which modes hold the given calibration (default: every mode that runs the calibration); the others "
                  "estimate it online")
      ->delimiter(',');
  cmd->add_option("-o,--out", options->out_dir, "Output folder (sequences are cached in OUT/sequences)")->capture_default_str();
  cmd->callback([options, &action] { action = [options] { return run_bench(*options); }; });
}

}  // namespace nirslam::app
