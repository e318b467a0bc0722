#include "nirslam/photometric/exposure_estimator.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace nirslam {

namespace {

double median_of(std::vector<double>& values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  double m = *middle;
  if (values.size() % 2 == 0) m = 0.5 * (m + *std::max_element(values.begin(), middle));
  return m;
}

}  // namespace

ExposureEstimator::ExposureEstimator(const ResponseModel& response, const VignetteModel& vignette,
                                     ExposureEstimatorOptions options)
    : options_(options) {
  if (options_.min_tracks < 1 || options_.min_valid_pixels < 1 || !(options_.black_level < options_.saturation_level))
    throw std::invalid_argument("exposure estimator: bad options");
  set_model(response, vignette);
}

void ExposureEstimator::set_model(const ResponseModel& response, const VignetteModel& vignette) {
  inverse_table_ = response.inverse_table(256);
  vignette_ = vignette;
  if (!anchors_.empty()) model_changed_ = true;
  anchors_.clear();
}

void ExposureEstimator::reset() {
  anchors_.clear();
  model_changed_ = false;
  illumination_modelled_ = false;
  log_exposure_.reset();
  last_ = {};
}

double ExposureEstimator::inverse_response(double y) const {
  const double position = std::clamp(y, 0.0, 1.0) * 255.0;
  const int i = std::min(static_cast<int>(position), 254);
  const double w = position - i;
  return (1.0 - w) * inverse_table_[static_cast<std::size_t>(i)] + w * inverse_table_[static_cast<std::size_t>(i) + 1];
}

bool ExposureEstimator::irradiance_patch(const cv::Mat& intensity, const Eigen::Vector2d& position,
                                         PatchSamples& irradiance) const {
  if (!(position.x() - kPatchRadius >= 0.0 && position.y() - kPatchRadius >= 0.0 &&
        position.x() + kPatchRadius < intensity.cols - 1 && position.y() + kPatchRadius < intensity.rows - 1))
    return false;
  const float lo = static_cast<float>(options_.black_level);
  const float hi = static_cast<float>(options_.saturation_level);
  const auto valid = [&](float y) { return y > lo && y < hi; };
  for (int i = 0; i < kPatchSide; ++i)
    for (int j = 0; j < kPatchSide; ++j) {
      const double x = position.x() + (j - kPatchRadius);
      const double y = position.y() + (i - kPatchRadius);
      const int x0 = static_cast<int>(x);
      const int y0 = static_cast<int>(y);
      const double fx = x - x0, fy = y - y0;
      const float* row0 = intensity.ptr<float>(y0) + x0;
      const float* row1 = intensity.ptr<float>(y0 + 1) + x0;
      float& out = irradiance[i * kPatchSide + j];
      if (!(valid(row0[0]) && valid(row0[1]) && valid(row1[0]) && valid(row1[1]))) {
        out = -1.0f;
        continue;
      }
      const double g = (1.0 - fy) * ((1.0 - fx) * inverse_response(row0[0]) + fx * inverse_response(row0[1])) +
                       fy * ((1.0 - fx) * inverse_response(row1[0]) + fx * inverse_response(row1[1]));
      out = static_cast<float>(g / vignette_(VignetteModel::radius(x, y, intensity.cols, intensity.rows)));
    }
  return true;
}

bool ExposureEstimator::log_irradiance_ratio(const PatchSamples& now, const PatchSamples& anchor,
                                             double& log_ratio) const {
  double sum_now = 0.0, sum_anchor = 0.0;
  int valid = 0;
  for (int k = 0; k < kPatchPixels; ++k) {
    // A pixel clipped in either frame carries no ratio: skip it in both sums.
    if (now[k] < 0.0f || anchor[k] < 0.0f) continue;
    sum_now += now[k];
    sum_anchor += anchor[k];
    ++valid;
  }
  if (valid < options_.min_valid_pixels || !(sum_now > 0.0) || !(sum_anchor > 0.0)) return false;
  log_ratio = std::log(sum_now / sum_anchor);
  return std::isfinite(log_ratio);
}

void ExposureEstimator::anchor_all(const TrackedFrame& tracked, double log_exposure, bool only_new,
                                   const std::vector<double>* log_illumination) {
  for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
    const std::int64_t id = tracked.tracks[i].id;
    if (!irradiance_valid_[i] || (only_new && anchors_.count(id) != 0)) continue;
    anchors_[id] = Anchor{irradiance_[i], log_exposure, log_illumination ? (*log_illumination)[i] : 0.0};
  }
}

const ExposureEstimate& ExposureEstimator::keep(const TrackedFrame& tracked, ExposureStatus status,
                                                std::string reason) {
  last_.frame_index = tracked.frame_index;
  last_.status = status;
  last_.reason = std::move(reason);
  last_.log_exposure_ratio = 0.0;
  last_.exposure = log_exposure_ ? std::optional<double>(std::exp(*log_exposure_)) : std::nullopt;
  return last_;
}

const ExposureEstimate& ExposureEstimator::update(const TrackedFrame& tracked) { return update(tracked, nullptr); }

const ExposureEstimate& ExposureEstimator::update(const TrackedFrame& tracked, const std::vector<double>* log_illumination) {
  if (log_illumination != nullptr && log_illumination->size() != tracked.tracks.size())
    throw std::invalid_argument("exposure estimator: " + std::to_string(log_illumination->size()) +
                                " light factors for " + std::to_string(tracked.tracks.size()) + " tracks");
  if ((log_illumination != nullptr) != illumination_modelled_) {
    // Anchors with and without the light's factor cannot be compared: restart the chain.
    if (!anchors_.empty()) model_changed_ = true;
    anchors_.clear();
    illumination_modelled_ = log_illumination != nullptr;
  }
  last_.used_tracks = 0;
  last_.inlier_tracks = 0;
  last_.log_sigma = 0.0;
  if (tracked.black_fraction > options_.max_black_fraction)
    return keep(tracked, ExposureStatus::BlackFrame,
                "black frame: " + std::to_string(static_cast<int>(100.0 * tracked.black_fraction)) +
                    " % of pixels at black; last estimate kept");
  if (tracked.saturated_fraction > options_.max_saturated_fraction)
    return keep(tracked, ExposureStatus::SaturatedFrame,
                "saturated frame: " + std::to_string(static_cast<int>(100.0 * tracked.saturated_fraction)) +
                    " % of pixels saturated; last estimate kept");

  const double reported = tracked.exposure_ms.value_or(1.0) * tracked.gain.value_or(1.0);
  const bool has_reported = tracked.exposure_ms.has_value() && std::isfinite(reported) && reported > 0.0;

  // Drop anchors of tracks the tracker lost; collect each surviving track's candidate log e_t.
  irradiance_.resize(tracked.tracks.size());
  irradiance_valid_.assign(tracked.tracks.size(), 0);
  int usable = 0;
  if (!tracked.intensity.empty() && tracked.intensity.type() == CV_32FC1)
    for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
      irradiance_valid_[i] = irradiance_patch(tracked.intensity, tracked.tracks[i].position, irradiance_[i]);
      usable += irradiance_valid_[i];
    }
  candidates_.clear();
  candidate_ids_.clear();
  std::unordered_map<std::int64_t, Anchor> alive;
  alive.reserve(tracked.tracks.size());
  for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
    const auto it = anchors_.find(tracked.tracks[i].id);
    if (it == anchors_.end()) continue;
    double log_ratio = 0.0;
    const double light_change = log_illumination ? (*log_illumination)[i] - it->second.log_illumination : 0.0;
    if (irradiance_valid_[i] && std::isfinite(light_change) &&
        log_irradiance_ratio(irradiance_[i], it->second.irradiance, log_ratio)) {
      candidates_.push_back(it->second.log_exposure + log_ratio - light_change);
      candidate_ids_.push_back(it->first);
    }
    alive.emplace(it->first, it->second);
  }
  anchors_.swap(alive);

  if (!log_exposure_ || anchors_.empty()) {
    if (usable < options_.min_tracks)
      return keep(tracked, log_exposure_ ? ExposureStatus::TooFewTracks : ExposureStatus::NoEstimateYet,
                  "too few tracks to anchor (" + std::to_string(usable) + " < " +
                      std::to_string(options_.min_tracks) + "); last estimate kept");
    const bool first = !log_exposure_;
    const double start = has_reported ? reported : (first ? 1.0 : std::exp(*log_exposure_));
    const double previous = log_exposure_.value_or(std::log(start));
    log_exposure_ = std::log(start);
    anchors_.clear();
    anchor_all(tracked, *log_exposure_, false, log_illumination);
    last_.frame_index = tracked.frame_index;
    last_.exposure = start;
    last_.log_exposure_ratio = *log_exposure_ - previous;
    last_.used_tracks = usable;
    last_.status = first ? ExposureStatus::FirstFrame : ExposureStatus::Restarted;
    const std::string why = model_changed_ ? "response/vignette or light model changed" : "all anchored tracks lost";
    last_.reason = first ? (has_reported ? "first frame: exposure x gain as reported" : "first frame: exposure set to 1")
                         : (has_reported ? why + ": restarted at the reported exposure x gain"
                                         : why + ": restarted at the last estimate (scale may jump)");
    model_changed_ = false;
    return last_;
  }

  if (static_cast<int>(candidates_.size()) < options_.min_tracks)
    return keep(tracked, ExposureStatus::TooFewTracks,
                "too few usable tracks (" + std::to_string(candidates_.size()) + " < " +
                    std::to_string(options_.min_tracks) + "); last estimate kept");

  // Median, MAD scale, then Huber IRLS: the median alone wastes most of the tracks' information.
  residuals_ = candidates_;
  double estimate = median_of(residuals_);
  for (std::size_t i = 0; i < candidates_.size(); ++i) residuals_[i] = std::abs(candidates_[i] - estimate);
  const double sigma = std::max(1.4826 * median_of(residuals_), options_.min_sigma);
  const double threshold = options_.huber_k * sigma;
  for (int iteration = 0; iteration < 10; ++iteration) {
    double weighted = 0.0, weights = 0.0;
    for (const double c : candidates_) {
      const double r = std::abs(c - estimate);
      const double w = r <= threshold ? 1.0 : threshold / r;
      weighted += w * c;
      weights += w;
    }
    const double next = weighted / weights;
    const bool converged = std::abs(next - estimate) < 1e-7;
    estimate = next;
    if (converged) break;
  }
  if (!std::isfinite(estimate))
    return keep(tracked, ExposureStatus::NotFinite, "robust fit not finite; last estimate kept");

  int inliers = 0;
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    if (std::abs(candidates_[i] - estimate) <= options_.outlier_sigmas * sigma) {
      ++inliers;
    } else {
      anchors_.erase(candidate_ids_[i]);  // re-anchored below at the new estimate
    }
  }
  last_.log_exposure_ratio = estimate - *log_exposure_;
  log_exposure_ = estimate;
  anchor_all(tracked, estimate, true, log_illumination);
  last_.frame_index = tracked.frame_index;
  last_.exposure = std::exp(estimate);
  last_.log_sigma = sigma;
  last_.used_tracks = static_cast<int>(candidates_.size());
  last_.inlier_tracks = inliers;
  last_.status = ExposureStatus::Estimated;
  last_.reason.clear();
  return last_;
}

}  // namespace nirslam
