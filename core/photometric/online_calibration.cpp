#include "nirslam/photometric/online_calibration.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

namespace nirslam {

std::string_view to_string(AmbiguityResolution resolution) {
  switch (resolution) {
    case AmbiguityResolution::KnownExposures: return "known exposures";
    case AmbiguityResolution::PowerSweep: return "power sweep";
    case AmbiguityResolution::Normalisation: return "normalisation";
    case AmbiguityResolution::Given: return "given calibration";
  }
  return "unknown";
}

namespace {

PhotometricBackendOptions backend_options(const OnlineCalibrationOptions& options) {
  PhotometricBackendOptions b = options.backend;
  b.trust_known_exposures = options.use_reported_exposures;
  if (options.response_from_power_sweep) {
    b.initial_response = *options.response_from_power_sweep;
    b.estimate_response = false;
  }
  return b;
}

// The grey range over which the exposure estimator trusts G (exposure_estimator.hpp): where the
// back end fitted it, unless the response is known over all levels (held from a power sweep or
// not estimated).
std::optional<std::pair<double, double>> trusted_grey_range(const OnlineCalibrationOptions& options,
                                                            const PhotometricEstimate& model) {
  if (options.response_from_power_sweep || !options.given_model.empty() || !options.backend.estimate_response ||
      !(model.grey_high > model.grey_low))
    return std::nullopt;
  return std::make_pair(model.grey_low, model.grey_high);
}

// log G at grey level `grey` (0..255), G in grey-level units.
double log_inverse_response(const ResponseModel& response, double grey) {
  return std::log(std::max(255.0 * response.inverse(grey / 255.0), 1e-9));
}

double milliseconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

std::string estimate_rejection(const EstimateGate& gate, const ResponseModel& response, double grey_low,
                               double grey_high, double residual_rms) {
  if (gate.max_residual_rms > 0.0 && residual_rms > gate.max_residual_rms)
    return fmt::format("residual {:.2f} grey levels > {:.2f}: the model does not fit these frames (a lamp's distance "
                       "change read as radiance change?)",
                       residual_rms, gate.max_residual_rms);
  if ((gate.max_response_slope > 0.0 || gate.min_response_slope > 0.0) && grey_high > grey_low) {
    // Slopes over steps of 10 % in grey level: fine enough to see a jump, coarse enough that
    // the 8-bit quantisation of the observed range does not matter.
    constexpr double kStep = 1.1;
    const double low = std::max(grey_low, 8.0);
    double steepest = 0.0, flattest = 1e9, steep_at = low, flat_at = low;
    for (double g = low; g * kStep <= grey_high; g *= kStep) {
      const double slope = (log_inverse_response(response, g * kStep) - log_inverse_response(response, g)) / std::log(kStep);
      if (slope > steepest) steepest = slope, steep_at = g;
      if (slope < flattest) flattest = slope, flat_at = g;
    }
    if (gate.max_response_slope > 0.0 && steepest > gate.max_response_slope)
      return fmt::format("response implausible: d log G / d log I = {:.1f} at grey {:.0f} (above {:.1f}) inside the "
                         "observed range {:.0f}-{:.0f}",
                         steepest, steep_at, gate.max_response_slope, grey_low, grey_high);
    if (gate.min_response_slope > 0.0 && flattest < gate.min_response_slope)
      return fmt::format("response implausible: d log G / d log I = {:.2f} at grey {:.0f} (below {:.2f}) inside the "
                         "observed range {:.0f}-{:.0f}",
                         flattest, flat_at, gate.min_response_slope, grey_low, grey_high);
  }
  return {};
}

namespace {

// The tracker estimates the tracks' deformation when either consumer follows the surface.
PhotometricTrackerOptions tracker_options(const OnlineCalibrationOptions& options) {
  PhotometricTrackerOptions tracker = options.tracker;
  tracker.estimate_deformation |= options.exposure.follow_deformation || options.keyframes_follow_deformation;
  return tracker;
}

}  // namespace

OnlinePhotometricCalibration::OnlinePhotometricCalibration(OnlineCalibrationOptions options)
    : options_(std::move(options)),
      tracker_(tracker_options(options_)),
      exposure_(backend_options(options_).initial_response, options_.backend.initial_vignette, options_.exposure),
      selector_(options_.keyframes),
      backend_(backend_options(options_)) {
  if (options_.queue_capacity < 1 || options_.iterations_per_keyframe < 1 || options_.final_iterations < 1)
    throw std::invalid_argument("online photometric calibration: bad options");
  if (!options_.given_model.empty()) options_.run_backend = false;  // a given calibration is held
  estimate_ = initial_estimate();
  exposure_.set_model(estimate_->response, estimate_->vignette, trusted_grey_range(options_, *estimate_));
  inverse_lut_.resize(256);  // filled by follow_estimate() before the first correction
  if (options_.background_thread && options_.run_backend) thread_ = std::thread([this] { backend_loop(); });
}

OnlinePhotometricCalibration::~OnlinePhotometricCalibration() {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stopping_ = true;
  }
  queue_changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

double OnlinePhotometricCalibration::keyframe_saturation_level(bool lamp_modelled) const {
  if (options_.keyframe_saturation_level >= 0.0) return options_.keyframe_saturation_level;
  const PhotometricResidualForm form = lamp_modelled ? options_.backend.lit_residual_form : options_.backend.residual_form;
  return options_.backend.clip_noise_grey > 0.0 && form == PhotometricResidualForm::PredictedGrey
             ? kFullScaleSaturationLevel
             : options_.tracker.saturation_level;
}

std::shared_ptr<const PhotometricEstimate> OnlinePhotometricCalibration::initial_estimate() const {
  auto e = std::make_shared<PhotometricEstimate>();
  e->response = backend_.response();
  e->vignette = backend_.vignette();
  e->response_determined =
      !options_.backend.estimate_response || options_.response_from_power_sweep.has_value() || !options_.given_model.empty();
  if (options_.backend.beam_halo) {
    e->beam_exponent = backend_.beam_exponent();
    e->beam_lens = options_.backend.beam_halo->lens();
  }
  if (!options_.given_model.empty()) {
    e->ambiguity = AmbiguityResolution::Given;
    e->ambiguity_detail = options_.given_model;
  } else if (options_.response_from_power_sweep) {
    e->ambiguity = AmbiguityResolution::PowerSweep;
    e->ambiguity_detail = "response calibrated from an illuminator power sweep and held";
  } else if (!options_.given_part.empty() && !options_.backend.estimate_response) {
    e->ambiguity = AmbiguityResolution::Given;
    e->ambiguity_detail = options_.given_part;
  } else {
    e->ambiguity = AmbiguityResolution::Normalisation;
    e->ambiguity_detail = "not yet decided (no keyframe yet)" + (options_.given_part.empty() ? "" : "; " + options_.given_part);
  }
  e->status = !options_.given_model.empty() ? "given calibration held (no online estimation)"
               : options_.run_backend         ? "no keyframe yet: initial model"
                                              : "back end off: initial model held";
  if (options_.initial_grey_range) {
    e->grey_low = options_.initial_grey_range->first;
    e->grey_high = options_.initial_grey_range->second;
  }
  return e;
}

std::shared_ptr<const PhotometricEstimate> OnlinePhotometricCalibration::estimate() const {
  std::lock_guard<std::mutex> lock(estimate_mutex_);
  return estimate_;
}

std::int64_t OnlinePhotometricCalibration::keyframes_dropped() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return dropped_;
}

std::int64_t OnlinePhotometricCalibration::illumination_filled() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return illumination_filled_;
}

void OnlinePhotometricCalibration::fill_unknown_illumination(std::int64_t frame_index, std::vector<TrackIllumination> values) {
  if (!options_.run_backend || values.empty()) return;
  Job job;
  job.kind = Job::Illumination;
  job.frame_index = frame_index;
  job.illumination = std::move(values);
  if (!options_.background_thread || !thread_.joinable()) {
    run_job(job);
    return;
  }
  {
    // Never dropped like a waiting keyframe: it is small, and its keyframe may still be waiting.
    std::lock_guard<std::mutex> lock(queue_mutex_);
    queue_.push_back(std::move(job));
  }
  queue_changed_.notify_all();
}

void OnlinePhotometricCalibration::follow_estimate(const PhotometricEstimate& model) {
  const VignetteModel& vignette = options_.correction_vignette ? *options_.correction_vignette : model.vignette;
  const bool first = correction_version_ < 0;
  if (!first && correction_response_.coefficients() == model.response.coefficients() &&
      correction_vignette_.v == vignette.v) {
    correction_model_version_ = model.model_version;
    return;  // caught up: nothing to measure
  }
  double largest = 0.0;
  if (!first && !correction_at_once_ && options_.max_correction_step_log > 0.0) {
    // How far the estimate is from the correction model, in log G over the grey range the fit
    // saw (outside it G is extrapolated and not what the frames mostly show) and in log V.
    const double low = model.grey_high > model.grey_low ? std::max(model.grey_low, 2.0) : 8.0;
    const double high = model.grey_high > model.grey_low ? std::min(model.grey_high, 253.0) : 247.0;
    for (double g = low; g <= high; g += (high - low) / 32.0) {
      const double now = correction_response_.inverse(g / 255.0), target = model.response.inverse(g / 255.0);
      if (now > 0.0 && target > 0.0) largest = std::max(largest, std::abs(std::log(target / now)));
    }
    for (double r = 0.0; r <= 1.0; r += 1.0 / 32.0) {
      const double now = correction_vignette_(r), target = vignette(r);
      if (now > 0.0 && target > 0.0) largest = std::max(largest, std::abs(std::log(target / now)));
    }
  }
  // Both models are linear in their coefficients, so a step along the coefficients is a blend of
  // two monotonic curves (itself monotonic) and of two vignettes.
  const double t =
      first || correction_at_once_ || largest <= options_.max_correction_step_log || options_.max_correction_step_log <= 0.0
          ? 1.0
          : options_.max_correction_step_log / largest;
  correction_model_version_ = t == 1.0 ? model.model_version : -1;
  if (t == 1.0) {
    correction_response_ = model.response;
    correction_vignette_ = vignette;
  } else {
    correction_response_ = ResponseModel(correction_response_.coefficients() +
                                         t * (model.response.coefficients() - correction_response_.coefficients()));
    correction_vignette_.v += t * (vignette.v - correction_vignette_.v);
  }
  const std::vector<double> table = correction_response_.inverse_table(256);
  for (int i = 0; i < 256; ++i) inverse_lut_[static_cast<std::size_t>(i)] = static_cast<float>(table[static_cast<std::size_t>(i)]);
  ++correction_version_;
}

void OnlinePhotometricCalibration::correct(const Frame& frame, const TrackedFrame& tracked, cv::Mat& out) {
  // Held (hold_correction): the frames keep the model they were corrected with; the first frame
  // still takes the estimate as it is.
  if (!correction_held_ || correction_version_ < 0) follow_estimate(*estimate());
  const int version = correction_version_;
  if (inverse_vignette_version_ != version || inverse_vignette_.cols != frame.width() ||
      inverse_vignette_.rows != frame.height()) {
    inverse_vignette_ = correction_vignette_.render(frame.width(), frame.height());
    cv::divide(1.0, inverse_vignette_, inverse_vignette_);
    inverse_vignette_version_ = version;
  }
  out.create(frame.height(), frame.width(), CV_32FC1);
  const float* lut = inverse_lut_.data();
  for (int y = 0; y < frame.height(); ++y) {
    const float* inv_v = inverse_vignette_.ptr<float>(y);
    float* o = out.ptr<float>(y);
    if (frame.image.type() == CV_8UC1) {
      const std::uint8_t* in = frame.image.ptr<std::uint8_t>(y);
      for (int x = 0; x < frame.width(); ++x) o[x] = lut[in[x]] * inv_v[x];
    } else {
      // Deeper frames: the tracker's intensity (fraction of full scale), G interpolated.
      const float* in = tracked.intensity.ptr<float>(y);
      for (int x = 0; x < frame.width(); ++x) {
        const float position = std::min(std::max(in[x], 0.0f), 1.0f) * 255.0f;
        const int i = std::min(static_cast<int>(position), 254);
        const float t = position - static_cast<float>(i);
        o[x] = ((1.0f - t) * lut[i] + t * lut[i + 1]) * inv_v[x];
      }
    }
  }
}

CorrectedFrame OnlinePhotometricCalibration::process(const Frame& frame) { return process_frame(frame, nullptr); }

CorrectedFrame OnlinePhotometricCalibration::process(const Frame& frame, const FrameIllumination& illumination) {
  return process_frame(frame, &illumination);
}

CorrectedFrame OnlinePhotometricCalibration::process_frame(const Frame& frame, const FrameIllumination* illumination) {
  const auto start = std::chrono::steady_clock::now();
  // A newer model from the back end: hand it to the exposure estimator and the correction.
  const std::shared_ptr<const PhotometricEstimate> model = estimate();
  if (model->model_version != applied_version_) {
    exposure_.set_model(model->response, model->vignette, trusted_grey_range(options_, *model));
    applied_version_ = model->model_version;
  }

  const TrackedFrame& tracked = tracker_.process(frame);
  const std::vector<double>* log_illumination = nullptr;
  if (illumination != nullptr && (illumination->light_distance_m || illumination->track_light_distance_m)) {
    const double power = lamp_power_w(*illumination, frame.illuminator_power_w);
    log_illumination_.resize(tracked.tracks.size());
    for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
      const Eigen::Vector2d& pixel = tracked.tracks[i].position;
      const std::int64_t id = tracked.tracks[i].id;
      std::optional<double> distance;
      if (illumination->track_light_distance_m) distance = illumination->track_light_distance_m(id, pixel);
      if (!distance && illumination->light_distance_m) distance = illumination->light_distance_m(pixel);
      log_illumination_[i] =
          illumination->track_light_cosine ? nirslam::log_illumination(power, distance, illumination->track_light_cosine(id, pixel))
          : illumination->light_cosine     ? nirslam::log_illumination(power, distance, illumination->light_cosine(pixel))
                                           : nirslam::log_illumination(power, distance);
    }
    log_illumination = &log_illumination_;
  }
  CorrectedFrame out;
  out.estimate = exposure_.update(tracked, log_illumination);
  out.exposure = out.estimate.exposure;
  out.model_version = applied_version_;
  std::optional<double> reported;
  if (frame.exposure_ms && std::isfinite(*frame.exposure_ms) && *frame.exposure_ms > 0.0)
    reported = *frame.exposure_ms * frame.gain.value_or(1.0);
  history_.push_back(ExposureSample{frame.index, frame.timestamp_s, out.estimate.updated() ? out.exposure : std::nullopt,
                                    reported, out.estimate.status});

  if (options_.run_backend) {
    const bool known = options_.use_reported_exposures && reported.has_value();
    // With a reported exposure the back end holds it, so the keyframe choice goes by it too: the
    // front end's estimate is then an output only (under a co-located lamp a constant-radiance
    // estimate moves with the lamp's distance, and keyframes chosen on it changed with the
    // estimator's details).
    const bool by_reported = known && options_.keyframes_by_reported_exposure;
    ExposureEstimate reported_estimate;  // only what the selector reads: not a copy of the estimate's text
    if (by_reported) {
      reported_estimate.frame_index = frame.index;
      reported_estimate.exposure = *reported;
      reported_estimate.status = ExposureStatus::Estimated;
    }
    const KeyframeDecision decision =
        selector_.consider(tracked, by_reported ? reported_estimate : out.estimate, frame.timestamp_s);
    if (decision.keyframe) {
      out.keyframe = true;
      Job job;
      job.kind = Job::Keyframe;
      job.keyframe = make_photometric_keyframe(tracked, frame.timestamp_s, known ? *reported : *out.exposure, known,
                                               options_.tracker.black_level,
                                               keyframe_saturation_level(log_illumination != nullptr),
                                               log_illumination, options_.keyframes_follow_deformation);
      if (!options_.background_thread) {
        run_job(job);
      } else {
        {
          std::lock_guard<std::mutex> lock(queue_mutex_);
          std::size_t waiting = 0;
          for (const Job& j : queue_) waiting += j.kind == Job::Keyframe;
          if (static_cast<int>(waiting) >= options_.queue_capacity) {
            // The back end lags: drop the oldest waiting keyframe (never a command).
            for (auto it = queue_.begin(); it != queue_.end(); ++it)
              if (it->kind == Job::Keyframe) {
                queue_.erase(it);
                ++dropped_;
                break;
              }
          }
          queue_.push_back(std::move(job));
        }
        queue_changed_.notify_all();
      }
    }
  }
  if (options_.correct_images) correct(frame, tracked, out.irradiance);
  out.front_end_ms = milliseconds_since(start);
  return out;
}

void OnlinePhotometricCalibration::publish(const BackendStep& step) {
  auto e = std::make_shared<PhotometricEstimate>();
  const std::shared_ptr<const PhotometricEstimate> previous = estimate();
  // The gate (EstimateGate): an estimate that fails it is not handed on; the last good one stays.
  const std::string rejection = step.ok && step.updated ? estimate_rejection(options_.gate, backend_.response(), step.grey_low,
                                                                             step.grey_high, step.residual_rms)
                                                        : std::string();
  e->estimates_rejected = previous->estimates_rejected + (rejection.empty() ? 0 : 1);
  if (step.ok && step.updated && rejection.empty()) {
    e->response = backend_.response();
    e->vignette = backend_.vignette();
    e->model_version = ++version_;
    if (options_.backend.beam_halo) {
      e->beam_exponent = backend_.beam_exponent();
      e->beam_lens = options_.backend.beam_halo->lens();
    }
    // The model's course through a run (`nirslam -v`): what drifted, and when.
    // gamma: the log-log slope of f^-1 between grey 64 and 128, free of the irradiance scale.
    spdlog::debug("photometric model v{}: {} keyframes in the window, {} points; response {} (f^-1(0.5) = {:.4f}, "
                  "gamma {:.3f}); vignette {} ({:.3f}, {:.3f}, {:.3f}){}; residual {:.2f} grey levels",
                  e->model_version, step.keyframes, step.points, step.response_estimated ? "estimated" : "held",
                  e->response.inverse(0.5),
                  std::log(e->response.inverse(128.0 / 255.0) / e->response.inverse(64.0 / 255.0)) / std::log(2.0),
                  step.vignette_estimated ? "estimated" : "held", e->vignette.v[0],
                  e->vignette.v[1], e->vignette.v[2],
                  e->beam_exponent ? fmt::format(", beam m {:.3f}", *e->beam_exponent) : std::string(),
                  step.residual_rms);
  } else {
    // Nothing new: the last good model, with the reason.
    e->response = previous->response;
    e->vignette = previous->vignette;
    e->model_version = previous->model_version;
    e->beam_exponent = previous->beam_exponent;
    e->beam_lens = previous->beam_lens;
  }
  e->converged = step.converged;
  e->iterations = step.iterations;
  e->cost = step.cost;
  e->residual_rms = step.residual_rms;
  e->keyframes = step.keyframes;
  e->points = step.points;
  e->backend_ms = last_backend_ms_;
  const bool adopted = step.ok && step.updated && rejection.empty();
  e->response_determined = previous->response_determined || (adopted && step.response_estimated && !step.lit);
  e->grey_low = adopted ? step.grey_low : previous->grey_low;
  e->grey_high = adopted ? step.grey_high : previous->grey_high;
  e->radius_high = adopted ? step.radius_high : previous->radius_high;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    e->keyframes_dropped = dropped_;
  }
  if (options_.response_from_power_sweep) {
    e->ambiguity = AmbiguityResolution::PowerSweep;
    e->ambiguity_detail = "response calibrated from an illuminator power sweep (radiance proportional to power) and held";
  } else if (!options_.given_part.empty() && !options_.backend.estimate_response) {
    e->ambiguity = AmbiguityResolution::Given;
    e->ambiguity_detail = options_.given_part + (saw_known_exposure_ ? "; the source's exposures held"
                                                                     : "; first frame's exposure = 1 (relative units)");
  } else if (saw_known_exposure_) {
    e->ambiguity = AmbiguityResolution::KnownExposures;
    e->ambiguity_detail = "exposure times x gain reported by the source hold the keyframe exposures";
  } else {
    e->ambiguity = AmbiguityResolution::Normalisation;
    if (options_.backend.gamma_gauge_weight > 0.0) {
      char detail[200];
      std::snprintf(detail, sizeof detail,
                    "first frame's exposure = 1 (relative units); gamma fixed by normalisation: f^-1(%.0f/255) pulled "
                    "to the initial response's %.4f",
                    options_.backend.gamma_gauge_grey,
                    options_.backend.initial_response.inverse(std::clamp(options_.backend.gamma_gauge_grey / 255.0, 0.01, 0.99)));
      e->ambiguity_detail = detail;
    } else {
      e->ambiguity_detail =
          "first frame's exposure = 1 (relative units); gamma NOT determined: pinned only by the response basis and "
          "the prior towards the initial response";
    }
  }
  if (!options_.given_part.empty() && e->ambiguity != AmbiguityResolution::Given)
    e->ambiguity_detail += "; " + options_.given_part;
  e->status = rejection.empty() ? step.status
                                : step.status + "; NOT USED, " + rejection + "; last good estimate (version " +
                                      std::to_string(previous->model_version) + ") kept";
  e->keyframe_exposures = backend_.keyframe_exposures();
  std::lock_guard<std::mutex> lock(estimate_mutex_);
  estimate_ = std::move(e);
}

void OnlinePhotometricCalibration::run_job(Job& job) {
  const auto start = std::chrono::steady_clock::now();
  switch (job.kind) {
    case Job::Keyframe: {
      saw_known_exposure_ |= job.keyframe.exposure_known && options_.use_reported_exposures;
      backend_.add_keyframe(std::move(job.keyframe));
      const BackendStep step = backend_.optimise(options_.iterations_per_keyframe);
      last_backend_ms_ = milliseconds_since(start);
      publish(step);
      break;
    }
    case Job::Illumination: {
      const std::size_t filled = backend_.fill_unknown_illumination(job.frame_index, job.illumination);
      std::lock_guard<std::mutex> lock(queue_mutex_);
      illumination_filled_ += static_cast<std::int64_t>(filled);
      break;
    }
    case Job::Finish: {
      const BackendStep step = backend_.optimise(options_.final_iterations, true);
      last_backend_ms_ = milliseconds_since(start);
      publish(step);
      break;
    }
    case Job::Reset: {
      backend_.reset();
      {
        std::lock_guard<std::mutex> lock(queue_mutex_);
        illumination_filled_ = 0;
      }
      version_ = 0;
      saw_known_exposure_ = false;
      last_backend_ms_ = 0.0;
      std::lock_guard<std::mutex> lock(estimate_mutex_);
      estimate_ = initial_estimate();
      break;
    }
  }
}

void OnlinePhotometricCalibration::backend_loop() {
  std::unique_lock<std::mutex> lock(queue_mutex_);
  for (;;) {
    queue_changed_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (stopping_) return;
    Job job = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    run_job(job);
    lock.lock();
    busy_ = false;
    queue_changed_.notify_all();
  }
}

void OnlinePhotometricCalibration::submit_and_wait(Job::Kind kind) {
  Job job;
  job.kind = kind;
  if (!options_.background_thread || !thread_.joinable()) {
    if (options_.run_backend || kind == Job::Reset) run_job(job);
    return;
  }
  std::unique_lock<std::mutex> lock(queue_mutex_);
  if (kind == Job::Reset) {
    // Waiting keyframes belong to the old run.
    std::erase_if(queue_, [](const Job& j) { return j.kind == Job::Keyframe || j.kind == Job::Illumination; });
  }
  queue_.push_back(std::move(job));
  queue_changed_.notify_all();
  queue_changed_.wait(lock, [this] { return stopping_ || (queue_.empty() && !busy_); });
}

void OnlinePhotometricCalibration::finish() { submit_and_wait(Job::Finish); }

std::vector<PhotometricKeyframe> OnlinePhotometricCalibration::stored_keyframes() const {
  const auto copy = [this] { return std::vector<PhotometricKeyframe>(backend_.keyframes().begin(), backend_.keyframes().end()); };
  if (!options_.background_thread || !thread_.joinable()) return copy();
  // With the queue empty and the back end idle under the lock, it cannot start another job until
  // the lock is let go: the keyframes are still.
  std::unique_lock<std::mutex> lock(queue_mutex_);
  queue_changed_.wait(lock, [this] { return stopping_ || (queue_.empty() && !busy_); });
  return copy();
}

void OnlinePhotometricCalibration::reset() {
  submit_and_wait(Job::Reset);
  tracker_.reset();
  exposure_.reset();
  selector_.reset();
  history_.clear();
  const std::shared_ptr<const PhotometricEstimate> model = estimate();
  exposure_.set_model(model->response, model->vignette, trusted_grey_range(options_, *model));
  exposure_.reset();
  applied_version_ = model->model_version;
  inverse_vignette_version_ = -1;
  correction_version_ = -1;  // a new start: the next frame is corrected with the estimate as it is
}

}  // namespace nirslam
