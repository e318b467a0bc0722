#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/source_argument.hpp"
#include "commands/subcommand.hpp"
#include "nirslam/session/session_format.hpp"
#include "nirslam/sources/frame_limit.hpp"
#include "nirslam/worker/worker.hpp"

namespace nirslam::app {
namespace {

struct RecordOptions {
  std::string source = kDefaultSource;
  std::filesystem::path session;
  std::int64_t max_frames = 0;
  std::string notes;
  std::string mode;  // empty: the configured one
  std::string format = "png";
  int png_compression = -1;  // -1: the configured default
  bool recorded_speed = false;
};

int record_headless(const RecordOptions& options) {
  SourceFactory factory = source_factory_from_argument(options.source);
  if (options.max_frames > 0) factory = [factory, n = options.max_frames] { return limit_frames(factory(), n); };

  WorkerOptions worker_options = app_config().worker;
  if (options.recorded_speed) worker_options.pacing = Pacing::RecordedSpeed;
  if (!options.mode.empty()) {
    const auto mode = parse_pipeline_mode(options.mode);
    if (!mode)
      throw std::invalid_argument(
          "--mode: expected quality, odometry, calibrated, illuminated or odometry-illuminated, got '" + options.mode + "'");
    worker_options.pipeline.mode = *mode;
    worker_options.pipeline_mode_automatic = false;
  }
  worker_options.recording.format = *parse_frame_file_format(options.format);
  if (options.png_compression >= 0) worker_options.recording.png_compression = options.png_compression;

  Worker worker(worker_options);
  worker.post(command::SetSource{factory});
  worker.post(command::StartRecording{options.session, options.notes});
  const auto started_or_refused = [](const Snapshot& s) {
    return s.recording.state != RecordingStatus::State::Off || s.state == WorkerState::Failed;
  };
  std::shared_ptr<const Snapshot> last = worker.wait_for(started_or_refused, std::chrono::seconds(60));
  if (last->state == WorkerState::Failed) {
    spdlog::error("{}", last->message);
    return 1;
  }
  if (last->recording.state != RecordingStatus::State::Recording) {
    spdlog::error("{}", last->recording.message.empty() ? last->message : last->recording.message);
    return 1;
  }
  spdlog::info("{}", last->recording.message);
  worker.post(command::Start{});

  const auto begin = std::chrono::steady_clock::now();
  while (!settled(*last)) {
    last = worker.wait_for(settled, std::chrono::seconds(1));
    if (last->frame && !settled(*last)) {
      const RecordingStatus& r = last->recording;
      spdlog::info("frame {}{} | written {} | {} | {} free{}{}", last->frames_processed,
                   last->source.frame_count ? "/" + std::to_string(*last->source.frame_count) : std::string(),
                   r.frames_written, human_bytes(r.bytes_written), human_bytes(r.free_bytes),
                   r.minutes_left ? fmt::format(" (~{:.0f} min left)", *r.minutes_left) : std::string(),
                   r.frames_dropped > 0 ? fmt::format(" | {} dropped", r.frames_dropped) : std::string());
    }
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  const RecordingStatus& r = last->recording;
  if (last->state == WorkerState::Failed) spdlog::error("the pipeline stopped: {}", last->message);
  if (r.state != RecordingStatus::State::Stopped) {
    spdlog::error("{}", r.message);
    return 1;
  }
  std::printf("Recorded %lld frames (%s, %lld dropped) in %.1f s to %s\n", static_cast<long long>(r.frames_written),
              human_bytes(r.bytes_written).c_str(), static_cast<long long>(r.frames_dropped), wall_s,
              options.session.string().c_str());
  return last->state == WorkerState::Failed ? 1 : 0;
}

}  // namespace

void add_record_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<RecordOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "record", "Record a session headless: every frame lossless (frames/), the per-frame journal (journal.csv), "
                "session.json, and what the pipeline estimated (trajectory, calibration) for `export`");
  cmd->add_option("source", options->source, kSourceArgumentHelp)->capture_default_str();
  cmd->add_option("-o,--out", options->session, "New session folder (must not exist or be empty)")->required();
  cmd->add_option("--frames", options->max_frames, "Stop after this many frames")->check(CLI::PositiveNumber);
  cmd->add_option("--notes", options->notes, "Operator notes, stored in session.json");
  cmd->add_option("--mode", options->mode, "Pipeline stages while recording: quality, odometry or calibrated "
                                            "(default from the config, pipeline.mode)")
      ->check(CLI::IsMember({"quality", "odometry", "calibrated"}));
  cmd->add_option("--format", options->format, "Frame files: png (lossless, compressed) or pgm (raw)")
      ->check(CLI::IsMember({"png", "pgm"}))
      ->capture_default_str();
  cmd->add_option("--png-level", options->png_compression, "PNG compression level 0..9 (default 1: keeps up with 30 fps)")
      ->check(CLI::Range(0, 9));
  cmd->add_flag("--realtime", options->recorded_speed, "Follow the source's timestamps instead of running flat out");
  cmd->callback([options, &action] { action = [options] { return record_headless(*options); }; });
}

}  // namespace nirslam::app
