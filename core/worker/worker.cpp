#include "nirslam/worker/worker.hpp"

#include <exception>
#include <stdexcept>
#include <tuple>
#include <type_traits>

#include <spdlog/spdlog.h>

#include "nirslam/quality/image_quality.hpp"
#include "nirslam/session/session_outputs.hpp"

namespace nirslam {
namespace {

double milliseconds_between(std::chrono::steady_clock::time_point from,
                            std::chrono::steady_clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

}  // namespace

PipelineMode automatic_pipeline_mode(const SourceInfo& source) {
  return source.reports_lamp_power ? PipelineMode::Illuminated : PipelineMode::Calibrated;
}

Worker::Worker(WorkerOptions options)
    : options_(std::move(options)),
      meter_(options_.quality),
      sweep_(options_.illumination),
      manual_illuminator_(options_.illumination.illuminator) {
  auto first = std::make_shared<Snapshot>();
  first->illumination = sweep_.status();
  set_pipeline_views(*first);
  latest_ = std::move(first);
  thread_ = std::thread([this] { run(); });
}

Worker::~Worker() {
  {
    std::lock_guard lock(queue_mutex_);
    exit_requested_ = true;
  }
  queue_cv_.notify_all();
  thread_.join();
  if (sweep_fit_.valid()) sweep_fit_.wait();
}

void Worker::post(Command command) {
  {
    std::lock_guard lock(queue_mutex_);
    queue_.push_back(std::move(command));
  }
  queue_cv_.notify_one();
}

std::shared_ptr<const Snapshot> Worker::snapshot() const {
  std::lock_guard lock(latest_mutex_);
  return latest_;
}

std::shared_ptr<const Snapshot> Worker::wait_for(const std::function<bool(const Snapshot&)>& done,
                                                 std::chrono::milliseconds timeout) const {
  std::unique_lock lock(latest_mutex_);
  published_cv_.wait_for(lock, timeout, [&] { return done(*latest_); });
  return latest_;
}

void Worker::set_observer(FrameObserver observer) {
  // Handed over under the queue lock; the worker thread moves it into observer_ between frames,
  // so it is the only thread that ever calls or replaces the active observer.
  {
    std::lock_guard lock(queue_mutex_);
    incoming_observer_ = std::move(observer);
  }
  queue_cv_.notify_one();
}

void Worker::set_finish_handler(FinishHandler handler) {
  {
    std::lock_guard lock(queue_mutex_);
    incoming_finish_handler_ = std::move(handler);
  }
  queue_cv_.notify_one();
}

void Worker::run() {
  while (true) {
    std::deque<Command> commands;
    {
      std::unique_lock lock(queue_mutex_);
      const auto has_work = [&] {
        return exit_requested_ || !queue_.empty() || incoming_observer_ || incoming_finish_handler_ || sweep_fit_ready_ ||
               state_ == WorkerState::Running ||
               steps_pending_ > 0;
      };
      queue_cv_.wait(lock, has_work);
      if (exit_requested_) {
        lock.unlock();
        // Closing while recording keeps the session complete, with what the pipeline has.
        finish_recording("the worker closed");
        return;
      }
      commands.swap(queue_);
      if (incoming_observer_) {
        observer_ = std::move(*incoming_observer_);
        incoming_observer_.reset();
      }
      if (incoming_finish_handler_) {
        finish_handler_ = std::move(*incoming_finish_handler_);
        incoming_finish_handler_.reset();
      }
    }
    for (Command& command : commands) apply(command);
    collect_sweep_fit();

    if (state_ == WorkerState::Running || steps_pending_ > 0) {
      if (pending_frame_) {
        // At recorded speed the next frame waits for its time; a command wakes the wait early.
        if (const auto deadline = pacing_deadline(pending_frame_->timestamp_s)) {
          std::unique_lock lock(queue_mutex_);
          if (queue_cv_.wait_until(lock, *deadline, [&] { return exit_requested_ || !queue_.empty(); }))
            continue;
        }
      }
      process_one_frame();
    }
  }
}

void Worker::apply(Command& command) {
  std::visit(
      [this](auto& c) {
        using C = std::decay_t<decltype(c)>;
        if constexpr (std::is_same_v<C, command::Start>) {
          if (!source_) return publish_state(WorkerState::Idle, "no source selected");
          if (state_ == WorkerState::Finished || state_ == WorkerState::Failed) rewind_source();
          pacing_origin_.reset();
          publish_state(WorkerState::Running, "running");
        } else if constexpr (std::is_same_v<C, command::Pause>) {
          if (state_ == WorkerState::Running) publish_state(WorkerState::Paused, "paused");
        } else if constexpr (std::is_same_v<C, command::Step>) {
          if (!source_) return publish_state(WorkerState::Idle, "no source selected");
          if (state_ == WorkerState::Finished || state_ == WorkerState::Failed) rewind_source();
          if (state_ != WorkerState::Running) {
            state_ = WorkerState::Paused;
            ++steps_pending_;
          }
        } else if constexpr (std::is_same_v<C, command::Stop>) {
          if (recorder_ && !recorder_finished_) finish_recording("stopped");
          rewind_source();
          publish_state(WorkerState::Idle, "stopped");
        } else if constexpr (std::is_same_v<C, command::Reset>) {
          if (recorder_ && !recorder_finished_) finish_recording("reset");
          rewind_source();
          history_.clear();
          frames_processed_ = 0;
          recent_completions_.clear();
          auto next = copy_of_latest();
          next->frame.reset();
          next->quality = {};
          next->structure = {};
          next->histogram = {};
          next->feature_grid = {};
          next->exposure = {};
          next->quality_history.clear();
          next->corrected_image = cv::Mat();
          set_pipeline_views(*next);
          next->frames_processed = 0;
          next->processing_fps = 0.0;
          next->state = state_ == WorkerState::Running ? state_ : WorkerState::Idle;
          next->message = "reset";
          state_ = next->state;
          publish(std::move(next));
        } else if constexpr (std::is_same_v<C, command::SetSource>) {
          if (recorder_ && !recorder_finished_) finish_recording("the source changed");
          recorder_.reset();
          recording_status_ = {};
          source_.reset();
          history_.clear();
          frames_processed_ = 0;
          recent_completions_.clear();
          pending_frame_.reset();
          steps_pending_ = 0;
          reset_sweep_response();  // another camera, perhaps
          if (given_before_hold_) {
            std::tie(options_.pipeline.given_calibration_folder, options_.pipeline.given_calibration_holds) =
                *given_before_hold_;
            given_before_hold_.reset();
          }
          auto next = std::make_shared<Snapshot>();
          next->sequence = snapshot()->sequence + 1;
          next->illuminator_power_w = power_w_;
          source_illuminator_.reset();
          try {
            source_ = c.make();
            source_illuminator_ = source_->illuminator();
            if (source_illuminator_) power_w_ = source_illuminator_->current_power_w();
            next->illuminator_power_w = power_w_;
            next->source = source_->info();
            next->state = state_ = WorkerState::Idle;
            next->message = "source ready: " + source_->info().description;
            if (options_.pipeline_mode_automatic) options_.pipeline.mode = automatic_pipeline_mode(source_->info());
            restart_pipeline();
          } catch (const std::exception& e) {
            next->state = state_ = WorkerState::Failed;
            next->message = e.what();
            spdlog::error("cannot open source: {}", e.what());
          }
          sweep_.set_illuminator(illuminator().capabilities());
          // A source that knows its scene (the simulator) selects the advisor's scene prior.
          if (source_ && !source_->info().scene_type.empty())
            sweep_.apply(sweep_command::SelectScene{source_->info().scene_type});
          next->illumination = sweep_.status();
          set_pipeline_views(*next);
          if (!pipeline_error_.empty()) next->message = pipeline_error_;
          publish(std::move(next));
        } else if constexpr (std::is_same_v<C, command::SetIlluminatorPower>) {
          std::string message;
          set_power(c.watts, message);
          auto next = copy_of_latest();
          next->illuminator_power_w = power_w_;
          next->message = std::move(message);
          publish(std::move(next));
        } else if constexpr (std::is_same_v<C, command::Sweep>) {
          std::string message;
          const auto* capture = std::get_if<sweep_command::Capture>(&c.action);
          // The lamp first: a capture at a power that cannot be set does not start.
          if (capture == nullptr || set_power(capture->power_w, message)) {
            const bool fresh = std::holds_alternative<sweep_command::Start>(c.action) ||
                               std::holds_alternative<sweep_command::Clear>(c.action);
            if (sweep_.apply(c.action) && fresh) reset_sweep_response();
            message = sweep_.status()->message;
            start_sweep_fit_if_complete();
          }
          auto next = copy_of_latest();
          next->sweep_response = sweep_response_;
          next->illuminator_power_w = power_w_;
          next->illumination = sweep_.status();
          next->message = std::move(message);
          publish(std::move(next));
        } else if constexpr (std::is_same_v<C, command::StartRecording>) {
          start_recording(c);
        } else if constexpr (std::is_same_v<C, command::StopRecording>) {
          if (!recorder_ || recorder_finished_) return publish_recording_status("no recording is running");
          publish_recording_status(finish_recording("stopped by the operator"));
        } else if constexpr (std::is_same_v<C, command::Seek>) {
          seek_source(c.position);
        } else if constexpr (std::is_same_v<C, command::HoldSweepResponse>) {
          hold_sweep_response(c);
        } else if constexpr (std::is_same_v<C, command::SetPacing>) {
          options_.pacing = c.pacing;
          pacing_origin_.reset();
        } else if constexpr (std::is_same_v<C, command::SetPipelineMode>) {
          options_.pipeline_mode_automatic = !c.mode.has_value();
          if (c.mode) options_.pipeline.mode = *c.mode;
          else if (source_) options_.pipeline.mode = automatic_pipeline_mode(source_->info());
          if (source_) restart_pipeline();
          auto next = copy_of_latest();
          set_pipeline_views(*next);
          next->corrected_image = cv::Mat();
          next->message = !pipeline_error_.empty() ? pipeline_error_
                          : c.mode                 ? fmt::format("pipeline mode: {}", to_string(*c.mode))
                                                   : fmt::format("pipeline mode: automatic ({} for this source)",
                                                                 to_string(options_.pipeline.mode));
          publish(std::move(next));
        }
      },
      command);
}

IlluminatorController& Worker::illuminator() {
  if (source_illuminator_) return *source_illuminator_;
  return manual_illuminator_;
}

bool Worker::set_power(double watts, std::string& message) {
  try {
    power_w_ = illuminator().set_power(watts);
    message = fmt::format("illuminator at {:g} W", *power_w_);
    return true;
  } catch (const std::exception& e) {
    message = e.what();
    spdlog::warn("{}", e.what());
    return false;
  }
}

std::optional<Worker::Clock::time_point> Worker::pacing_deadline(double timestamp_s) {
  if (options_.pacing != Pacing::RecordedSpeed || steps_pending_ > 0) return std::nullopt;
  if (!pacing_origin_) {
    pacing_origin_ = std::make_pair(Clock::now(), timestamp_s);
    return std::nullopt;
  }
  const auto offset = std::chrono::duration<double>(timestamp_s - pacing_origin_->second);
  return pacing_origin_->first + std::chrono::duration_cast<Clock::duration>(offset);
}

void Worker::process_one_frame() {
  const auto started = Clock::now();
  const bool single_step = steps_pending_ > 0;
  if (single_step) --steps_pending_;
  if (!source_) return publish_state(WorkerState::Idle, "no source selected");

  std::optional<Frame> frame;
  try {
    if (pending_frame_) {
      frame = std::move(pending_frame_);
      pending_frame_.reset();
    } else {
      frame = source_->next();
      if (frame && options_.pacing == Pacing::RecordedSpeed && !single_step) {
        // Read ahead of time so decoding does not delay the frame past its deadline.
        const auto deadline = pacing_deadline(frame->timestamp_s);
        if (deadline && *deadline > Clock::now()) {
          pending_frame_ = std::move(frame);
          return;
        }
      }
    }
    if (frame) validate_frame(*frame, frame->name.empty() ? source_->info().description : frame->name);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return publish_state(WorkerState::Failed, e.what());
  }

  if (!frame) {
    if (options_.loop && frames_processed_ > 0) {
      // A session's timestamps only go forward: the recording ends with the first pass.
      if (recorder_ && !recorder_finished_) finish_recording("end of source (the source loops)");
      rewind_source();
      return;
    }
    // A camera that went away says so (and how to resume); a dataset simply ended.
    std::string message = source_->end_reason();
    if (message.empty()) message = "end of sequence";
    if (pipeline_) {
      try {
        pipeline_->finish();
        if (finish_handler_) finish_handler_(*pipeline_);
      } catch (const std::exception& e) {
        spdlog::error("{}", e.what());
        if (recorder_ && !recorder_finished_) finish_recording("end of source");
        return publish_state(WorkerState::Failed, e.what());
      }
    }
    if (recorder_ && !recorder_finished_) message += "; " + finish_recording("end of source");
    auto next = copy_of_latest();
    if (pipeline_) set_pipeline_views(*next);
    next->recording = recording_status_;
    next->state = state_ = WorkerState::Finished;
    next->message = std::move(message);
    return publish(std::move(next));
  }
  const auto read_done = Clock::now();

  GreyHistogram histogram;
  FeatureGrid grid;
  const FrameMetrics metrics = meter_.measure(*frame, &histogram, &grid);
  const ImageQuality& quality = metrics.quality;
  const auto quality_done = Clock::now();

  PipelineFrameResult stages;
  if (pipeline_) {
    try {
      stages = pipeline_->process(*frame);
    } catch (const std::exception& e) {
      spdlog::error("{}", e.what());
      return publish_state(WorkerState::Failed, e.what());
    }
  }
  const auto pipeline_done = Clock::now();
  // The power of the frame: as the frame reports it (a lamp the source drives), else as the operator set it.
  const bool power_from_frame = frame->illuminator_power_w.has_value();
  sweep_.add_frame(metrics, power_from_frame ? frame->illuminator_power_w : power_w_, power_from_frame);
  keep_sweep_shot(*frame);
  start_sweep_fit_if_complete();

  QualitySample sample;
  sample.frame_index = frame->index;
  sample.timestamp_s = frame->timestamp_s;
  sample.quality = quality;
  sample.gradient_energy = static_cast<float>(metrics.structure.gradient_energy);
  sample.feature_coverage = static_cast<float>(metrics.structure.coverage);
  sample.feature_evenness = static_cast<float>(metrics.structure.evenness);
  sample.feature_count = metrics.structure.feature_count;
  history_.push_back(sample);
  while (history_.size() > options_.history_length) history_.pop_front();
  ++frames_processed_;
  recent_completions_.push_back(pipeline_done);
  while (pipeline_done - recent_completions_.front() > std::chrono::seconds(1))
    recent_completions_.pop_front();

  auto next = std::make_shared<Snapshot>();
  next->sequence = snapshot()->sequence + 1;
  next->state = state_ = single_step ? WorkerState::Paused : state_;
  next->source = source_->info();
  next->frame = std::move(frame);
  next->quality = quality;
  next->structure = metrics.structure;
  next->histogram = histogram;
  next->feature_grid = std::move(grid);
  next->exposure = check_exposure(quality, sweep_.config().exposure);
  next->illumination = sweep_.status();
  next->sweep_response = sweep_response_;
  next->quality_history.assign(history_.begin(), history_.end());
  next->timings.read_ms = milliseconds_between(started, read_done);
  next->timings.quality_ms = milliseconds_between(read_done, quality_done);
  next->timings.photometric_ms = stages.timings.photometric_ms;
  next->timings.odometry_ms = stages.timings.odometry_ms;
  next->timings.mapping_ms = stages.timings.mapping_ms;
  next->corrected_image = std::move(stages.corrected);
  if (stages.odometry) {
    next->stages.tracking = to_string(stages.odometry->status);
    next->stages.keyframe = stages.odometry->is_keyframe;
    next->stages.residual_rms = stages.odometry->residual_rms;
  }
  if (stages.photometric) next->stages.exposure_estimate = stages.photometric->exposure;
  set_pipeline_views(*next);
  next->timings.total_ms = milliseconds_between(started, Clock::now());
  next->frames_processed = frames_processed_;
  next->frames_dropped = source_->frames_dropped();
  const double window_s =
      std::chrono::duration<double>(pipeline_done - recent_completions_.front()).count();
  next->processing_fps =
      recent_completions_.size() > 1 && window_s > 0.0 ? (recent_completions_.size() - 1) / window_s : 0.0;
  next->illuminator_power_w = power_w_;
  next->message = state_ == WorkerState::Paused ? "paused" : "running";
  if (observer_) {
    try {
      observer_(*next);
    } catch (const std::exception& e) {
      // A writer that cannot keep up (full disk) stops processing; frames already written stay.
      spdlog::error("{}", e.what());
      next->state = state_ = WorkerState::Failed;
      next->message = e.what();
    }
  }
  if (recorder_ && !recorder_finished_) {
    if (recorder_->recording()) {
      // Queued only: the recorder's thread writes it; a full queue counts a dropped frame.
      FrameAnnotations annotations;
      annotations.entropy_bits = quality.entropy_bits;
      if (stages.odometry) annotations.T_world_cam = stages.odometry->T_world_cam;
      recording_status_ = recorder_->status();
      next->recording = recording_status_;
      recorder_->record(*next->frame, annotations, next);
    } else {
      // The recorder stopped itself (full disk, write error): finalise the session, keep going.
      finish_recording("write error");
      next->recording = recording_status_;
      next->message = recording_status_.message;
    }
  } else {
    next->recording = recording_status_;
  }
  publish(std::move(next));
}

void Worker::start_recording(const command::StartRecording& start) {
  if (recorder_ && !recorder_finished_)
    return publish_recording_status("already recording to " + recorder_->folder().string());
  if (!source_) return publish_recording_status("no source selected: choose a source before recording");
  RecordingSourceInfo info;
  info.kind = source_->info().kind;
  info.description = source_->info().description;
  info.nominal_fps = source_->info().nominal_fps;
  info.camera = source_->camera();
  RecorderOptions options = options_.recording;
  options.notes = start.notes;
  try {
    recorder_.reset();
    recorder_ = std::make_unique<SessionRecorder>(start.folder, std::move(info), std::move(options));
    recorder_finished_ = false;
    recording_status_ = recorder_->status();
    publish_recording_status(recording_status_.message);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    recorder_.reset();
    recorder_finished_ = true;
    recording_status_ = {};
    recording_status_.state = RecordingStatus::State::Failed;
    recording_status_.folder = start.folder.string();
    recording_status_.last_error = e.what();
    recording_status_.message = std::string("cannot start recording: ") + e.what();
    publish_recording_status(recording_status_.message);
  }
}

std::string Worker::finish_recording(const std::string& reason) {
  if (!recorder_ || recorder_finished_) return recording_status_.message;
  recorder_finished_ = true;
  const bool failed = recorder_->status().state == RecordingStatus::State::Failed;
  if (pipeline_ && !failed) {
    CalibrationOutputInfo info;
    info.source = source_ ? source_->info().description : std::string();
    info.frames = frames_processed_;
    const std::shared_ptr<const Snapshot> latest = snapshot();
    if (latest->frame) {
      info.width = latest->frame->width();
      info.height = latest->frame->height();
    }
    try {
      for (std::string& name : write_pipeline_outputs(*pipeline_, recorder_->folder(), info))
        recorder_->add_output(std::move(name));
    } catch (const std::exception& e) {
      spdlog::error("session outputs: {}", e.what());
    }
  }
  recording_status_ = recorder_->stop(reason);
  return recording_status_.message;
}

void Worker::publish_recording_status(std::string message) {
  auto next = copy_of_latest();
  next->recording = recording_status_;
  next->message = std::move(message);
  publish(std::move(next));
}

void Worker::rewind_source() {
  pending_frame_.reset();
  pacing_origin_.reset();
  steps_pending_ = 0;
  if (!source_) return;
  try {
    source_->rewind();
    restart_pipeline();
  } catch (const std::exception& e) {
    publish_state(WorkerState::Failed, e.what());
  }
}

void Worker::seek_source(std::size_t position) {
  // A refused jump changes nothing but the message.
  const auto refuse = [this](std::string message) { publish_state(state_, std::move(message)); };
  if (!source_) return refuse("no source selected");
  if (!source_->info().seekable) return refuse(fmt::format("{}: this source cannot jump to a frame", source_->info().description));
  if (recorder_ && !recorder_finished_) return refuse("cannot jump while recording: stop the recording first");
  try {
    source_->seek(position);
  } catch (const std::exception& e) {
    return refuse(e.what());
  }
  pending_frame_.reset();
  pacing_origin_.reset();
  restart_pipeline();
  steps_pending_ = 0;
  if (state_ != WorkerState::Running) {
    state_ = WorkerState::Paused;
    steps_pending_ = 1;  // show the frame jumped to
  }
  auto next = copy_of_latest();
  next->state = state_;
  set_pipeline_views(*next);
  next->corrected_image = cv::Mat();
  next->message = fmt::format("jumped to frame {}; calibration and odometry start again there", position + 1);
  publish(std::move(next));
}

void Worker::keep_sweep_shot(const Frame& frame) {
  const std::optional<double> power = sweep_.last_captured_w();
  if (!power) return;
  sweep_shots_.add(*power, frame);
  sweep_shots_unfitted_ = true;
}

void Worker::start_sweep_fit_if_complete() {
  if (!sweep_shots_unfitted_ || sweep_.status()->progress.stage != SweepStage::Complete) return;
  sweep_shots_unfitted_ = false;
  if (sweep_fit_.valid()) {  // an earlier sweep's fit, not collected yet: dropped
    sweep_fit_.wait();
    sweep_fit_ = {};
    std::lock_guard lock(queue_mutex_);
    sweep_fit_ready_ = false;
  }
  auto fitting = std::make_shared<SweepResponse>();
  if (sweep_shots_.shots().empty() && (sweep_shots_.missing_exposure() > 0 || sweep_shots_.unusable_images() > 0)) {
    fitting->state = SweepResponse::State::Failed;
    fitting->reason = sweep_shots_.missing_exposure() > 0
                          ? "the source reports no exposure time with its frames; the response needs power x exposure"
                          : "the source's frames are not 8- or 16-bit grey images; the response is fitted on grey levels";
    sweep_response_ = std::move(fitting);
    return;
  }
  sweep_response_ = std::move(fitting);
  sweep_fit_generation_ = sweep_generation_;
  sweep_fit_ = std::async(std::launch::async, [this, shots = sweep_shots_.shots()] {
    SweepResponse response = fit_sweep_response(shots);
    {
      std::lock_guard lock(queue_mutex_);
      sweep_fit_ready_ = true;
    }
    queue_cv_.notify_one();
    return response;
  });
}

void Worker::collect_sweep_fit() {
  {
    std::lock_guard lock(queue_mutex_);
    if (!sweep_fit_ready_) return;
    sweep_fit_ready_ = false;
  }
  if (!sweep_fit_.valid()) return;
  SweepResponse response = sweep_fit_.get();
  if (sweep_fit_generation_ != sweep_generation_) return;  // a new sweep started meanwhile
  const std::string message =
      response.state == SweepResponse::State::Done
          ? fmt::format("camera response from the sweep: {} images, residual {:.2f} grey levels{}", response.images,
                        response.residual_rms_grey, response.warning.empty() ? "" : "; " + response.warning)
          : "no camera response from the sweep: " + response.reason;
  sweep_response_ = std::make_shared<const SweepResponse>(std::move(response));
  auto next = copy_of_latest();
  next->sweep_response = sweep_response_;
  next->message = message;
  publish(std::move(next));
}

void Worker::reset_sweep_response() {
  sweep_shots_.clear();
  sweep_shots_unfitted_ = false;
  sweep_response_.reset();
  ++sweep_generation_;
}

void Worker::hold_sweep_response(const command::HoldSweepResponse& hold) {
  auto next = copy_of_latest();
  if (!sweep_response_ || sweep_response_->state != SweepResponse::State::Done) {
    next->message = "no camera response from a complete power sweep to hold";
    return publish(std::move(next));
  }
  auto held = std::make_shared<SweepResponse>(*sweep_response_);
  try {
    write_sweep_response(*held, hold.folder);
  } catch (const std::exception& e) {
    next->message = std::string("cannot hold the sweep's response: ") + e.what();
    spdlog::error("{}", next->message);
    return publish(std::move(next));
  }
  held->folder = hold.folder;
  held->held = true;
  if (!given_before_hold_)
    given_before_hold_.emplace(options_.pipeline.given_calibration_folder, options_.pipeline.given_calibration_holds);
  options_.pipeline.given_calibration_folder = hold.folder;
  options_.pipeline.given_calibration_holds = GivenCalibrationParts::Response;
  restart_pipeline();
  sweep_response_ = std::move(held);
  set_pipeline_views(*next);
  next->corrected_image = cv::Mat();
  next->sweep_response = sweep_response_;
  next->message = !pipeline_error_.empty()
                      ? pipeline_error_
                      : fmt::format("the pipeline holds the sweep's response ({})", (hold.folder / "pcalib.txt").string());
  publish(std::move(next));
}

void Worker::restart_pipeline() {
  pipeline_.reset();  // the old calibration thread ends before the new one starts
  pipeline_error_.clear();
  if (!source_) return;
  try {
    pipeline_ = std::make_unique<SlamPipeline>(options_.pipeline, source_->camera(), source_->photometric_truth());
  } catch (const std::exception& e) {
    pipeline_error_ = std::string("pipeline: ") + e.what();
    spdlog::error("{}", pipeline_error_);
  }
}

void Worker::set_pipeline_views(Snapshot& snapshot) {
  snapshot.pipeline_mode = std::string(to_string(options_.pipeline.mode));
  snapshot.pipeline_mode_automatic = options_.pipeline_mode_automatic;
  snapshot.pipeline_error = pipeline_error_;
  if (pipeline_) {
    snapshot.photometric = pipeline_->photometric_view();
    snapshot.trajectory = pipeline_->trajectory_view();
    return;
  }
  auto photometric = std::make_shared<PhotometricView>();
  photometric->status = pipeline_error_;
  auto trajectory = std::make_shared<TrajectoryView>();
  trajectory->message = pipeline_error_.empty() ? "no source" : pipeline_error_;
  snapshot.photometric = std::move(photometric);
  snapshot.trajectory = std::move(trajectory);
}

void Worker::publish_state(WorkerState state, std::string message) {
  state_ = state;
  auto next = copy_of_latest();
  next->state = state;
  next->message = std::move(message);
  publish(std::move(next));
}

std::shared_ptr<Snapshot> Worker::copy_of_latest() const {
  auto next = std::make_shared<Snapshot>(*snapshot());
  ++next->sequence;
  return next;
}

void Worker::publish(std::shared_ptr<Snapshot> next) {
  std::shared_ptr<const Snapshot> previous = std::move(next);
  {
    std::lock_guard lock(latest_mutex_);
    latest_.swap(previous);
  }
  published_cv_.notify_all();
  // `previous` (possibly the last reference to an old frame) is released here, outside the lock.
}

}  // namespace nirslam
