#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/source_argument.hpp"
#include "commands/subcommand.hpp"
#include "nirslam/session/metrics_csv_writer.hpp"
#include "nirslam/sources/frame_limit.hpp"
#include "nirslam/worker/worker.hpp"

namespace nirslam::app {
namespace {

struct RunOptions {
  std::string source = kDefaultSource;
  std::filesystem::path out_dir = "nirslam-run";
  bool recorded_speed = false;
  std::int64_t max_frames = 0;
  double progress_interval_s = 1.0;
};

bool settled(const Snapshot& s) {
  return s.state == WorkerState::Finished || s.state == WorkerState::Failed;
}

void write_summary(const std::filesystem::path& file, const RunOptions& options, const Snapshot& last,
                   double wall_s, double mean_entropy) {
  nlohmann::json summary = {
      {"nirslam_version", NIRSLAM_VERSION},
      {"source", {{"argument", options.source}, {"kind", last.source.kind}, {"description", last.source.description}}},
      {"state", to_string(last.state)},
      {"message", last.message},
      {"frames_processed", last.frames_processed},
      {"frames_dropped", last.frames_dropped},
      {"wall_time_s", wall_s},
      {"frames_per_second", wall_s > 0 ? last.frames_processed / wall_s : 0.0},
      {"mean_entropy_bits", mean_entropy},
  };
  std::ofstream out(file);
  out << summary.dump(2) << '\n';
  if (!out) throw std::runtime_error(file.string() + ": cannot write the run summary");
}

int run_headless(const RunOptions& options) {
  SourceFactory factory = source_factory_from_argument(options.source);
  if (options.max_frames > 0)
    factory = [factory, n = options.max_frames] { return limit_frames(factory(), n); };

  std::error_code error;
  std::filesystem::create_directories(options.out_dir, error);
  if (error) throw std::runtime_error(options.out_dir.string() + ": cannot create output folder (" + error.message() + ")");

  auto csv = std::make_shared<MetricsCsvWriter>(options.out_dir / "quality.csv");
  double entropy_sum = 0.0;  // written by the worker thread, read here once it has settled
  WorkerOptions worker_options = app_config().worker;
  if (options.recorded_speed) worker_options.pacing = Pacing::RecordedSpeed;
  Worker worker(worker_options);
  worker.set_observer([csv, &entropy_sum](const Snapshot& s) {
    csv->write(s);
    entropy_sum += s.quality.entropy_bits;
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
      spdlog::info("frame {}{} | entropy {:.3f} bit | {:.1f} fps", last->frames_processed,
                   total ? "/" + std::to_string(*total) : std::string(), last->quality.entropy_bits,
                   last->processing_fps);
    }
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  // Every observer call happened on the worker thread before the settled snapshot was published,
  // and loading that snapshot orders them before the reads below.
  const double mean_entropy = last->frames_processed > 0 ? entropy_sum / static_cast<double>(last->frames_processed) : 0.0;
  write_summary(options.out_dir / "summary.json", options, *last, wall_s, mean_entropy);

  if (last->state == WorkerState::Failed) {
    spdlog::error("stopped after {} frames: {}", last->frames_processed, last->message);
    std::printf("Partial results (%lld frames) in %s\n", static_cast<long long>(csv->rows()),
                options.out_dir.string().c_str());
    return 1;
  }
  std::printf("Processed %lld frames in %.2f s (%.1f fps), mean entropy %.3f bit\n",
              static_cast<long long>(last->frames_processed), wall_s,
              wall_s > 0 ? last->frames_processed / wall_s : 0.0, mean_entropy);
  std::printf("Wrote %s and %s\n", csv->path().string().c_str(),
              (options.out_dir / "summary.json").string().c_str());
  return 0;
}

}  // namespace

void add_run_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "run", "Process a sequence headless and write per-frame metrics (quality.csv) and a summary");
  cmd->add_option("source", options->source, kSourceArgumentHelp)->capture_default_str();
  cmd->add_option("-o,--out", options->out_dir, "Output folder")->capture_default_str();
  cmd->add_flag("--realtime", options->recorded_speed,
                "Follow the recorded timestamps instead of running flat out (config: worker.pacing)");
  cmd->add_option("--max-frames", options->max_frames, "Stop after this many frames")->check(CLI::PositiveNumber);
  cmd->callback([options, &action] { action = [options] { return run_headless(*options); }; });
}

}  // namespace nirslam::app
