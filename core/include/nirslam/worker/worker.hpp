#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
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
#include "nirslam/quality/frame_metrics.hpp"
#include "nirslam/sources/source.hpp"
#include "nirslam/worker/snapshot.hpp"

namespace nirslam {

using SourceFactory = std::function<std::unique_ptr<Source>()>;

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
// The power sweep wizard (illumination/sweep_recorder.hpp). A Capture also sets the illuminator to
// its power first, as SetIlluminatorPower does.
struct Sweep { SweepCommand action; };
}  // namespace command

using Command = std::variant<command::Start, command::Pause, command::Step, command::Stop,
                             command::Reset, command::SetSource, command::SetIlluminatorPower,
                             command::SetPacing, command::Sweep>;

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

private:
  using Clock = std::chrono::steady_clock;

  void run();
  void apply(Command& command);
  void process_one_frame();
  void rewind_source();
  void publish_state(WorkerState state, std::string message);
  void publish(std::shared_ptr<Snapshot> next);
  std::shared_ptr<Snapshot> copy_of_latest() const;
  std::optional<Clock::time_point> pacing_deadline(double timestamp_s);
  IlluminatorController& illuminator();
  bool set_power(double watts, std::string& message);

  // Touched by the worker thread only.
  WorkerOptions options_;
  std::unique_ptr<Source> source_;
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

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<Command> queue_;
  std::optional<FrameObserver> incoming_observer_;
  bool exit_requested_ = false;

  // Held only to copy or swap the pointer (never while processing), so snapshot() returns within
  // nanoseconds whatever the worker is doing. libstdc++ 12's std::atomic<std::shared_ptr> was
  // tried first; ThreadSanitizer cannot follow its internal lock bit.
  mutable std::mutex latest_mutex_;
  std::shared_ptr<const Snapshot> latest_;
  mutable std::condition_variable published_cv_;
  std::thread thread_;  // last: starts after every member above exists
};

}  // namespace nirslam
