#include "nirslam/photometric/exposure_estimator.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

#include <Eigen/LU>

namespace nirslam {

namespace {

// The value where the cumulative weight of the sorted values reaches half of the total (the mean
// of the two middle values when it lands exactly on half: with equal weights, the plain median).
double weighted_median(const std::vector<double>& values, const std::vector<double>& weights,
                       std::vector<std::pair<double, double>>& buffer) {
  buffer.clear();
  double total = 0.0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    buffer.emplace_back(values[i], weights[i]);
    total += weights[i];
  }
  std::sort(buffer.begin(), buffer.end());
  double cumulative = 0.0;
  for (std::size_t i = 0; i < buffer.size(); ++i) {
    cumulative += buffer[i].second;
    if (cumulative == 0.5 * total && i + 1 < buffer.size()) return 0.5 * (buffer[i].first + buffer[i + 1].first);
    if (cumulative >= 0.5 * total) return buffer[i].first;
  }
  return buffer.back().first;
}

// A 256-entry table over grey levels at y (fraction of full scale), linearly interpolated.
double interpolate_grey_table(const std::vector<double>& table, double y) {
  const double position = std::clamp(y, 0.0, 1.0) * 255.0;
  const int i = std::min(static_cast<int>(position), 254);
  const double w = position - i;
  return (1.0 - w) * table[static_cast<std::size_t>(i)] + w * table[static_cast<std::size_t>(i) + 1];
}

}  // namespace

ExposureEstimator::ExposureEstimator(const ResponseModel& response, const VignetteModel& vignette,
                                     ExposureEstimatorOptions options)
    : options_(options) {
  if (options_.min_tracks < 1 || options_.min_valid_pixels < 1 || !(options_.black_level < options_.saturation_level))
    throw std::invalid_argument("exposure estimator: bad options");
  set_model(response, vignette);
}

void ExposureEstimator::set_model(const ResponseModel& response, const VignetteModel& vignette,
                                  std::optional<std::pair<double, double>> trusted_grey) {
  inverse_table_ = response.inverse_table(256);
  grey_weight_.assign(256, 1.0);
  if (trusted_grey && trusted_grey->second > trusted_grey->first) {
    const double width = std::max(options_.trust_width_grey, 1e-6);
    for (int i = 0; i < 256; ++i) {
      const double outside = std::max({trusted_grey->first - i, i - trusted_grey->second, 0.0});
      grey_weight_[static_cast<std::size_t>(i)] =
          std::max(std::exp(-0.5 * (outside / width) * (outside / width)), options_.min_grey_weight);
    }
  }
  vignette_ = vignette;
  if (!anchors_.empty()) model_changed_ = true;
  for (auto& [id, anchor] : anchors_) resample(anchor);
}

void ExposureEstimator::reset() {
  anchors_.clear();
  model_changed_ = false;
  illumination_modelled_ = false;
  log_exposure_.reset();
  last_ = {};
}

double ExposureEstimator::inverse_response(double y) const { return interpolate_grey_table(inverse_table_, y); }

double ExposureEstimator::grey_weight(double y) const { return interpolate_grey_table(grey_weight_, y); }

bool ExposureEstimator::irradiance_patch(const cv::Mat& intensity, const Eigen::Vector2d& position,
                                         const Eigen::Matrix2d& deformation, PatchSamples& irradiance,
                                         PatchSamples& weight) const {
  // The grid's extent: its corners under A (the farthest samples along either axis).
  const Eigen::Vector2d reach = kPatchRadius * deformation.cwiseAbs().rowwise().sum();
  if (!(position.x() - reach.x() >= 0.0 && position.y() - reach.y() >= 0.0 &&
        position.x() + reach.x() < intensity.cols - 1 && position.y() + reach.y() < intensity.rows - 1))
    return false;
  for (int i = 0; i < kPatchSide; ++i)
    for (int j = 0; j < kPatchSide; ++j) {
      const Eigen::Vector2d sample = position + deformation * Eigen::Vector2d(j - kPatchRadius, i - kPatchRadius);
      const double x = sample.x(), y = sample.y();
      const int x0 = static_cast<int>(x);
      const int y0 = static_cast<int>(y);
      const double fx = x - x0, fy = y - y0;
      const float* row0 = intensity.ptr<float>(y0) + x0;
      const float* row1 = intensity.ptr<float>(y0 + 1) + x0;
      irradiance_sample(row0[0], row0[1], row1[0], row1[1], fx, fy, x, y, intensity.cols, intensity.rows,
                        irradiance[i * kPatchSide + j], weight[i * kPatchSide + j]);
    }
  return true;
}

void ExposureEstimator::irradiance_sample(float c00, float c01, float c10, float c11, double fx, double fy, double x,
                                          double y, int cols, int rows, float& irradiance, float& weight) const {
  const float lo = static_cast<float>(options_.black_level);
  const float hi = static_cast<float>(options_.saturation_level);
  const auto valid = [&](float v) { return v > lo && v < hi; };
  if (!(valid(c00) && valid(c01) && valid(c10) && valid(c11))) {
    irradiance = -1.0f;
    weight = 0.0f;
    return;
  }
  // The least trusted of the four grey values the sample is interpolated from.
  weight = static_cast<float>(std::min({grey_weight(c00), grey_weight(c01), grey_weight(c10), grey_weight(c11)}));
  const double g = (1.0 - fy) * ((1.0 - fx) * inverse_response(c00) + fx * inverse_response(c01)) +
                   fy * ((1.0 - fx) * inverse_response(c10) + fx * inverse_response(c11));
  irradiance = static_cast<float>(g / vignette_(VignetteModel::radius(x, y, cols, rows)));
}

void ExposureEstimator::resample(Anchor& anchor) const {
  constexpr int kWindowSide = kPatchSide + 1;
  const GreyWindow& w = anchor.grey;
  const double fx = w.position.x() - static_cast<int>(w.position.x());
  const double fy = w.position.y() - static_cast<int>(w.position.y());
  for (int i = 0; i < kPatchSide; ++i)
    for (int j = 0; j < kPatchSide; ++j) {
      const int k = i * kWindowSide + j;
      irradiance_sample(w.grey[k], w.grey[k + 1], w.grey[k + kWindowSide], w.grey[k + kWindowSide + 1], fx, fy,
                        w.position.x() + (j - kPatchRadius), w.position.y() + (i - kPatchRadius), image_cols_, image_rows_,
                        anchor.irradiance[i * kPatchSide + j], anchor.weight[i * kPatchSide + j]);
    }
}

bool ExposureEstimator::log_irradiance_ratio(const PatchSamples& now, const PatchSamples& now_weight,
                                             const PatchSamples& anchor, const PatchSamples& anchor_weight,
                                             double& log_ratio, double& trust) const {
  double sum_now = 0.0, sum_anchor = 0.0, sum_weight = 0.0;
  int valid = 0;
  for (int k = 0; k < kPatchPixels; ++k) {
    // A pixel clipped in either frame carries no ratio: skip it in both sums.
    if (now[k] < 0.0f || anchor[k] < 0.0f) continue;
    const double w = std::min(now_weight[k], anchor_weight[k]);
    sum_now += w * now[k];
    sum_anchor += w * anchor[k];
    sum_weight += w;
    ++valid;
  }
  if (valid < options_.min_valid_pixels || !(sum_now > 0.0) || !(sum_anchor > 0.0)) return false;
  trust = sum_weight / valid;
  log_ratio = std::log(sum_now / sum_anchor);
  return std::isfinite(log_ratio);
}

void ExposureEstimator::anchor_all(const TrackedFrame& tracked, double log_exposure, bool only_new,
                                   const std::vector<double>* log_illumination) {
  for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
    const std::int64_t id = tracked.tracks[i].id;
    if (!irradiance_valid_[i] || (only_new && anchors_.count(id) != 0)) continue;
    // A track without the light's factor here (no distance yet) is anchored once it has one:
    // anchored now, every later ratio to this anchor would be unknown for the track's whole life.
    if (log_illumination != nullptr && !std::isfinite((*log_illumination)[i])) continue;
    Anchor& anchor = anchors_[id];
    anchor = Anchor{irradiance_[i], weight_[i], GreyWindow{}, log_exposure, log_illumination ? (*log_illumination)[i] : 0.0,
                    Eigen::Matrix2d::Identity(), tracked.tracks[i].surface};
    // The fixed window's samples share their sub-pixel fractions (irradiance_patch; the patch fits,
    // so the window does).
    const Eigen::Vector2d& position = tracked.tracks[i].position;
    const int x0 = static_cast<int>(position.x()) - kPatchRadius, y0 = static_cast<int>(position.y()) - kPatchRadius;
    for (int r = 0; r <= kPatchSide; ++r) {
      const float* row = tracked.intensity.ptr<float>(y0 + r) + x0;
      for (int c = 0; c <= kPatchSide; ++c) anchor.grey.grey[r * (kPatchSide + 1) + c] = row[c];
    }
    anchor.grey.position = position;
    // The anchor's window is the fixed one; later patches are mapped back to it (see the header).
    if (options_.follow_deformation) anchor.deformation_inverse = tracked.tracks[i].deformation.inverse();
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

  // A new model with a reported exposure: restart the chain there (see set_model).
  if (model_changed_ && has_reported) anchors_.clear();
  if (!tracked.intensity.empty()) {
    image_cols_ = tracked.intensity.cols;
    image_rows_ = tracked.intensity.rows;
  }

  // Drop anchors of tracks the tracker lost; collect each surviving track's candidate log e_t.
  irradiance_.resize(tracked.tracks.size());
  weight_.resize(tracked.tracks.size());
  irradiance_valid_.assign(tracked.tracks.size(), 0);
  int usable = 0;
  if (!tracked.intensity.empty() && tracked.intensity.type() == CV_32FC1)
    for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
      irradiance_valid_[i] = irradiance_patch(tracked.intensity, tracked.tracks[i].position, Eigen::Matrix2d::Identity(),
                                             irradiance_[i], weight_[i]);
      usable += irradiance_valid_[i];
    }
  if (options_.follow_deformation && !tracked.deformation_estimated)
    throw std::invalid_argument("exposure estimator: follow_deformation needs the tracks' deformation "
                                "(PhotometricTrackerOptions::estimate_deformation)");
  candidates_.clear();
  candidate_trust_.clear();
  candidate_ids_.clear();
  std::unordered_map<std::int64_t, Anchor> alive;
  alive.reserve(tracked.tracks.size());
  for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
    const auto it = anchors_.find(tracked.tracks[i].id);
    if (it == anchors_.end()) continue;
    double log_ratio = 0.0, trust = 1.0;
    const double light_change = log_illumination ? (*log_illumination)[i] - it->second.log_illumination : 0.0;
    // The patch over the same surface as at the anchor (see the header): sampled under A unless
    // that is the fixed window to within a hundredth of a pixel at its corners.
    // A track on a new surface since its anchor (its deformation was lost) gives no candidate and
    // is re-anchored at this frame's estimate.
    const PatchSamples* now = &irradiance_[i];
    const PatchSamples* now_weight = &weight_[i];
    bool sampled = irradiance_valid_[i] != 0;
    if (options_.follow_deformation) {
      if (tracked.tracks[i].surface != it->second.surface) continue;  // not kept in `alive`: re-anchored below
      const Eigen::Matrix2d a = tracked.tracks[i].deformation * it->second.deformation_inverse;
      if (sampled && (a - Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff() * kPatchRadius > 0.01) {
        sampled = irradiance_patch(tracked.intensity, tracked.tracks[i].position, a, warped_irradiance_, warped_weight_);
        now = &warped_irradiance_;
        now_weight = &warped_weight_;
      }
    }
    if (sampled && std::isfinite(light_change) &&
        log_irradiance_ratio(*now, *now_weight, it->second.irradiance, it->second.weight, log_ratio, trust)) {
      candidates_.push_back(it->second.log_exposure + log_ratio - light_change);
      candidate_trust_.push_back(trust);
      candidate_ids_.push_back(it->first);
    }
    alive.emplace(it->first, std::move(it->second));
  }
  anchors_.swap(alive);

  std::string few_anchored;
  // When too few anchored tracks give a candidate now but enough tracks could (anchors clipped in
  // a bright first frame, most anchored tracks lost while new ones came; under the lamp, patches
  // whose distances came and went: a track counts only with a light factor), restart the chain on
  // them, as when all anchored tracks are lost: else no new track is ever anchored (anchoring
  // happens after an estimate) and the last estimate is kept until the last anchored track dies.
  if (log_exposure_ && static_cast<int>(candidates_.size()) < options_.min_tracks) {
    int could = 0;
    for (std::size_t i = 0; i < tracked.tracks.size(); ++i)
      could += irradiance_valid_[i] && (log_illumination == nullptr || std::isfinite((*log_illumination)[i]));
    if (could >= options_.min_tracks) {
      anchors_.clear();
      if (!model_changed_) few_anchored = "too few anchored tracks usable (" + std::to_string(candidates_.size()) + ")";
    }
  }
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
    const std::string why = model_changed_          ? std::string("response/vignette or light model changed")
                            : !few_anchored.empty() ? few_anchored
                                                    : std::string("all anchored tracks lost");
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
  // Each candidate counts with its track's trust in G (all 1 without a trusted grey range).
  double estimate = weighted_median(candidates_, candidate_trust_, sorted_);
  residuals_.resize(candidates_.size());
  for (std::size_t i = 0; i < candidates_.size(); ++i) residuals_[i] = std::abs(candidates_[i] - estimate);
  const double sigma = std::max(1.4826 * weighted_median(residuals_, candidate_trust_, sorted_), options_.min_sigma);
  const double threshold = options_.huber_k * sigma;
  for (int iteration = 0; iteration < 10; ++iteration) {
    double weighted = 0.0, weights = 0.0;
    for (std::size_t i = 0; i < candidates_.size(); ++i) {
      const double c = candidates_[i];
      const double r = std::abs(c - estimate);
      const double w = candidate_trust_[i] * (r <= threshold ? 1.0 : threshold / r);
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
  if (model_changed_) last_.reason = "response/vignette or light model changed: anchors sampled again under it";
  model_changed_ = false;
  return last_;
}

}  // namespace nirslam
