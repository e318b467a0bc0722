#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <thread>
#include <variant>

#include "nirslam/config/illumination_config.hpp"
#include "nirslam/illumination/illuminator.hpp"
#include "nirslam/illumination/sweep_recorder.hpp"
#include "nirslam/illumination/sweep_response.hpp"
#include "nirslam/pipeline/slam_pipeline.hpp"
#include "nirslam/quality/frame_metrics.hpp"
#include "nirslam/session/session_recorder.hpp"
#include "nirslam/sources/source.hpp"
#include "nirslam/worker/snapshot.hpp"

namespace nirslam {

using SourceFactory = std::function<std::unique_ptr<Source>()>;

// The automatic mode's choice: with the lamp's model ('illuminated') when the source reports a
// lamp that lights its frames, since calibration alone takes the lamp's falloff for exposure and
// response (README, Table 2: 22 % lower ATE with the model); else 'calibrated'.
PipelineMode automatic_pipeline_mode(const SourceInfo& source);

enum class Pacing {
  AsFastAsPossible,  // datasets: every frame, no waiting
  RecordedSpeed,     // datasets: follow the timestamps
};

struct WorkerOptions {
  Pacing pacing = Pacing::AsFastAsPossible;
  std::size_t history_length = 600;  // quality samples kept in each snapshot
  bool loop = false;                 // restart the source at its end instead of finishing
  QualityOptions quality{};          // FAST threshold and coverage grid of the per-frame metrics
  IlluminationConfig illumination = default_illumination_config();  // advisor, sweep plan, priors
  PipelineOptions pipeline{};        // which stages run (mode) and their settings
  // pipeline.mode chosen per source instead (config `pipeline.mode: auto`):
  // automatic_pipeline_mode(), until a SetPipelineMode names a mode.
  bool pipeline_mode_automatic = false;
  RecorderOptions recording{};       // file format, PNG level, queue, free-space limits of recordings
};

namespace command {
struct Start {};                   // begin or resume processing
struct Pause {};
struct Step {};                    // process exactly one frame, then stay paused
struct Stop {};                    // stop and rewind the source; the last snapshot stays
struct Reset {};                   // rewind and clear history
struct SetSource { SourceFactory make; };  // replace the source (opened on the worker thread)
// Sets the illuminator: the source's own lamp when it has one (simulator, demo), else the manual
// controller records the power the operator set by hand. Out-of-range powers are refused with a
// message.
struct SetIlluminatorPower { double watts; };
struct SetPacing { Pacing pacing; };
// Switches the pipeline mode; the stages restart (calibration and odometry from scratch) with
// the next frame, the source keeps its place. No mode: automatic (automatic_pipeline_mode(), and
// again for every source opened after).
struct SetPipelineMode { std::optional<PipelineMode> mode; };
// The power sweep wizard (illumination/sweep_recorder.hpp). A Capture also sets the illuminator to
// its power first, as SetIlluminatorPower does.
struct Sweep { SweepCommand action; };
// Records every frame processed from now on into a new session folder (session/session_recorder.hpp)
// with the operator's notes; refused with a message when the folder is not empty, the disk has too
// little space or a recording is running. Snapshot::recording shows its progress.
struct StartRecording {
  std::filesystem::path folder;
  std::string notes;
};
// Ends the recording: writes the pipeline's trajectory, keyframes, points and calibration into the
// session, then the final session.json. Also happens at the end of the source, on Stop, Reset and
// SetSource, and when the worker closes.
struct StopRecording {};
// Jumps to frame `position` of a seekable source (SourceInfo::seekable: datasets, recorded
// sessions). The calibration and the odometry start again there, as on a new sequence: the frames
// before the jump are not the ones before it in time. When not running, the worker pauses on that
// frame (it is processed, so the feed shows it). Refused with a message for a source that cannot
// seek, a position past the end, and while a recording runs (the session would get a gap).
struct Seek { std::size_t position; };
// Writes the camera response fitted from the last power sweep (Snapshot::sweep_response, done)
// into `folder` (pcalib.txt, sweep_response.json) and holds it in the pipeline from the next
// frame (given_calibration_folder = folder, given_holds: response; the stages restart, the
// exposures and the halo factor estimated online). Refused with a message without such a response
// or when the folder cannot be written. Until the source changes: the next source gets the given
// calibration of before (it may be another camera).
struct HoldSweepResponse { std::filesystem::path folder; };
}  // namespace command

using Command = std::variant<command::Start, command::Pause, command::Step, command::Stop,
                             command::Reset, command::SetSource, command::SetIlluminatorPower,
                             command::SetPacing, command::Sweep, command::SetPipelineMode,
                             command::StartRecording, command::StopRecording, command::Seek,
                             command::HoldSweepResponse>;

// Owns a source and the pipeline in its own thread. The UI (or a headless writer) posts commands
// and reads the latest immutable snapshot; neither call waits for frame processing.
class Worker {
public:
  explicit Worker(WorkerOptions options = {});
  ~Worker();  // stops the thread and joins it
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  void post(Command command);
  std::shared_ptr<const Snapshot> snapshot() const;

  // For tests and headless front ends: blocks the caller (never the worker) until a snapshot
  // satisfies `done` or the timeout passes. Returns the last snapshot seen.
  std::shared_ptr<const Snapshot> wait_for(const std::function<bool(const Snapshot&)>& done,
                                           std::chrono::milliseconds timeout) const;

  // Frames the worker consumed are handed to these callbacks on the worker thread, e.g. a recorder
  // or a CSV writer. It must be fast; it runs before the snapshot is published. Takes effect before
  // the next frame.
  using FrameObserver = std::function<void(const Snapshot&)>;
  void set_observer(FrameObserver observer);

  // Called on the worker thread when the source ends, after the pipeline's finish() (the
  // calibration's final optimisation) and before the Finished snapshot is published: batch writers
  // read the odometry's final trajectory and the calibration from it. An exception it throws turns
  // the state into Failed with its message. Set it before Start.
  using FinishHandler = std::function<void(const SlamPipeline&)>;
  void set_finish_handler(FinishHandler handler);

private:
  using Clock = std::chrono::steady_clock;

  void run();
  void apply(Command& command);
  void process_one_frame();
  void rewind_source();
  void seek_source(std::size_t position);
  // A fresh pipeline for the current source (its camera and ground truth) and options_.pipeline.
  void restart_pipeline();
  void set_pipeline_views(Snapshot& snapshot);
  void publish_state(WorkerState state, std::string message);
  void publish(std::shared_ptr<Snapshot> next);
  std::shared_ptr<Snapshot> copy_of_latest() const;
  std::optional<Clock::time_point> pacing_deadline(double timestamp_s);
  IlluminatorController& illuminator();
  bool set_power(double watts, std::string& message);
  void start_recording(const command::StartRecording& start);
  // Writes the pipeline's outputs into the session (unless the recording failed: the disk is
  // full) and finalises it; returns the status message. No-op without a recorder.
  std::string finish_recording(const std::string& reason);
  void publish_recording_status(std::string message);
  // The power sweep's response (sweep_response.hpp): the wizard's frames kept while it captures,
  // fitted on a thread of its own once the sweep is complete, the result collected when ready.
  void keep_sweep_shot(const Frame& frame);
  void start_sweep_fit_if_complete();
  void collect_sweep_fit();
  void reset_sweep_response();
  void hold_sweep_response(const command::HoldSweepResponse& hold);

  // Touched by the worker thread only.
  WorkerOptions options_;
  std::unique_ptr<Source> source_;
  std::unique_ptr<SlamPipeline> pipeline_;
  std::string pipeline_error_;  // why the pipeline could not be built for this source
  FrameObserver observer_;
  WorkerState state_ = WorkerState::Idle;
  int steps_pending_ = 0;  // Step commands not yet served
  std::optional<double> power_w_;
  QualityMeter meter_;
  SweepRecorder sweep_;
  ManualIlluminator manual_illuminator_;
  std::shared_ptr<IlluminatorController> source_illuminator_;  // the source's own lamp, if any
  std::int64_t frames_processed_ = 0;
  std::deque<QualitySample> history_;
  std::deque<Clock::time_point> recent_completions_;
  std::optional<Frame> pending_frame_;  // read early, waiting for its time at recorded speed
  std::optional<std::pair<Clock::time_point, double>> pacing_origin_;  // wall time, stamp
  std::unique_ptr<SessionRecorder> recorder_;  // while a recording runs, and until the next starts
  bool recorder_finished_ = true;              // recorder_ has been stopped and finalised
  RecordingStatus recording_status_;           // as last published
  SweepShots sweep_shots_;
  bool sweep_shots_unfitted_ = false;  // shots kept since the last fit started
  std::shared_ptr<const SweepResponse> sweep_response_;  // null until a sweep completes
  std::uint64_t sweep_generation_ = 0;  // a fit of an older sweep is dropped when it arrives
  std::uint64_t sweep_fit_generation_ = 0;
  // The given calibration before HoldSweepResponse replaced it: restored for the next source,
  // which may be another camera.
  std::optional<std::pair<std::filesystem::path, GivenCalibrationParts>> given_before_hold_;

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<Command> queue_;
  std::optional<FrameObserver> incoming_observer_;
  std::optional<FinishHandler> incoming_finish_handler_;
  FinishHandler finish_handler_;  // worker thread only
  bool exit_requested_ = false;
  bool sweep_fit_ready_ = false;  // the fit's thread has its result (under queue_mutex_)
  std::future<SweepResponse> sweep_fit_;  // after the mutex and the condition it signals

  // Held only to copy or swap the pointer (never while processing), so snapshot() returns within
  // nanoseconds whatever the worker is doing. libstdc++ 12's std::atomic<std::shared_ptr> was
  // tried first; ThreadSanitizer cannot follow its internal lock bit.
  mutable std::mutex latest_mutex_;
  std::shared_ptr<const Snapshot> latest_;
  mutable std::condition_variable published_cv_;
  std::thread thread_;  // last: starts after every member above exists
};

}  // namespace nirslam
