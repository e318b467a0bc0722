#include "nirslam/photometric/keyframe_selection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace nirslam {

Eigen::Vector2d backend_pixel_offset(int k) {
  return Eigen::Vector2d(static_cast<double>((k % 3 - 1) * kBackendPixelPitch),
                         static_cast<double>((k / 3 - 1) * kBackendPixelPitch));
}

Eigen::Vector2d KeyframeObservation::pixel(int k) const {
  return position + deformation.cast<double>() * backend_pixel_offset(k);
}

namespace {

// bilinear_sample where it is defined; false outside.
bool bilinear(const cv::Mat& image, double x, double y, float& value) {
  if (!(x >= 0.0 && y >= 0.0 && x < image.cols - 1 && y < image.rows - 1)) return false;
  value = bilinear_sample(image, x, y);
  return true;
}

}  // namespace

PhotometricKeyframe make_photometric_keyframe(const TrackedFrame& tracked, double timestamp_s, double exposure,
                                              bool exposure_known, double black_level, double saturation_level,
                                              const std::vector<double>* log_illumination, bool follow_surfaces) {
  if (follow_surfaces && (!tracked.deformation_estimated || tracked.intensity.empty() || tracked.intensity.type() != CV_32FC1))
    throw std::invalid_argument("photometric keyframe: following the surface needs the tracks' deformation and the frame");
  PhotometricKeyframe keyframe;
  keyframe.frame_index = tracked.frame_index;
  keyframe.timestamp_s = timestamp_s;
  keyframe.width = tracked.width;
  keyframe.height = tracked.height;
  keyframe.exposure = exposure;
  keyframe.exposure_known = exposure_known;
  keyframe.illumination_modelled = log_illumination != nullptr;
  keyframe.black_grey = static_cast<float>(255.0 * black_level);
  keyframe.saturation_grey = static_cast<float>(255.0 * saturation_level);
  // The grey value, or the marker saying why it is not a normal sample (see the header).
  const auto grey_or_marker = [&](float y) {
    if (!(y > black_level)) return kGreyDark;
    if (!(y < saturation_level)) return kGreySaturated;
    return 255.0f * y;
  };
  keyframe.observations.reserve(tracked.tracks.size());
  const auto at = [](const PatchSamples& s, int row, int col) { return s[row * kPatchSide + col]; };
  for (std::size_t t = 0; t < tracked.tracks.size(); ++t) {
    const TrackObservation& track = tracked.tracks[t];
    KeyframeObservation o;
    o.track_id = track.id;
    o.position = track.position;
    if (log_illumination != nullptr && t < log_illumination->size())
      o.log_illumination = static_cast<float>((*log_illumination)[t]);
    int kept = 0;  // normal or saturated samples (dark ones alone do not keep an observation)
    if (follow_surfaces) {
      // The grid where the surface it covered at the surface's start is now (see the header): the
      // grey value and the central-difference gradient (1 px steps in this frame) at each pixel.
      o.deformation = track.deformation.cast<float>();
      o.surface = track.surface;
      for (int k = 0; k < kBackendPixels; ++k) {
        const Eigen::Vector2d p = o.pixel(k);
        float y = 0.0f, left = 0.0f, right = 0.0f, up = 0.0f, down = 0.0f;
        const bool inside = bilinear(tracked.intensity, p.x(), p.y(), y) &&
                            bilinear(tracked.intensity, p.x() - 1.0, p.y(), left) &&
                            bilinear(tracked.intensity, p.x() + 1.0, p.y(), right) &&
                            bilinear(tracked.intensity, p.x(), p.y() - 1.0, up) &&
                            bilinear(tracked.intensity, p.x(), p.y() + 1.0, down);
        const float gx = 0.5f * 255.0f * (right - left), gy = 0.5f * 255.0f * (down - up);
        o.gradient_sq[static_cast<std::size_t>(k)] = inside ? gx * gx + gy * gy : 0.0f;
        o.grey[static_cast<std::size_t>(k)] = inside ? grey_or_marker(y) : kGreyMissing;
        kept += o.grey[static_cast<std::size_t>(k)] != kGreyMissing && o.grey[static_cast<std::size_t>(k)] != kGreyDark;
      }
      if (kept > 0) keyframe.observations.push_back(o);
      continue;
    }
    for (int k = 0; k < kBackendPixels; ++k) {
      // Patch row/column of the pixel: the 3 x 3 grid at -3, 0, +3 around the centre (4, 4).
      const int row = kPatchRadius + (k / 3 - 1) * kBackendPixelPitch;
      const int col = kPatchRadius + (k % 3 - 1) * kBackendPixelPitch;
      const float y = at(track.samples, row, col);
      const float gx = 0.5f * 255.0f * (at(track.samples, row, col + 1) - at(track.samples, row, col - 1));
      const float gy = 0.5f * 255.0f * (at(track.samples, row + 1, col) - at(track.samples, row - 1, col));
      o.gradient_sq[static_cast<std::size_t>(k)] = gx * gx + gy * gy;
      o.grey[static_cast<std::size_t>(k)] = grey_or_marker(y);
      kept += o.grey[static_cast<std::size_t>(k)] != kGreyDark;
    }
    if (kept > 0) keyframe.observations.push_back(o);
  }
  return keyframe;
}

KeyframeDecision KeyframeSelector::consider(const TrackedFrame& tracked, const ExposureEstimate& estimate,
                                            double timestamp_s) {
  KeyframeDecision decision;
  if (!estimate.updated() || !estimate.exposure || !(*estimate.exposure > 0.0)) {
    decision.reason = "no exposure estimate for this frame (" + (estimate.reason.empty() ? std::string("kept") : estimate.reason) + ")";
    return decision;
  }
  if (static_cast<int>(tracked.tracks.size()) < options_.min_tracks) {
    decision.reason = "too few tracks (" + std::to_string(tracked.tracks.size()) + ")";
    return decision;
  }
  const double log_exposure = std::log(*estimate.exposure);
  std::vector<std::pair<std::int64_t, Eigen::Vector2d>> tracks;
  tracks.reserve(tracked.tracks.size());
  for (const TrackObservation& t : tracked.tracks) tracks.emplace_back(t.id, t.position);
  std::sort(tracks.begin(), tracks.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

  const auto accept = [&](std::string reason) {
    decision.keyframe = true;
    decision.reason = std::move(reason);
    last_ = Last{timestamp_s, log_exposure, std::move(tracks)};
    return decision;
  };
  if (!last_) return accept("first keyframe");
  const double dt = timestamp_s - last_->timestamp_s;
  if (dt < options_.min_interval_s) {
    decision.reason = "too soon after the last keyframe";
    return decision;
  }
  char text[96];
  const double exposure_change = std::abs(log_exposure - last_->log_exposure);
  if (exposure_change >= options_.min_log_exposure_change) {
    std::snprintf(text, sizeof text, "exposure changed by %.1f %%", 100.0 * (std::exp(exposure_change) - 1.0));
    return accept(text);
  }
  // Shared tracks (both lists sorted by id) and their mean shift.
  std::size_t shared = 0;
  double motion = 0.0;
  for (std::size_t i = 0, j = 0; i < tracks.size() && j < last_->tracks.size();) {
    if (tracks[i].first < last_->tracks[j].first) {
      ++i;
    } else if (tracks[i].first > last_->tracks[j].first) {
      ++j;
    } else {
      motion += (tracks[i].second - last_->tracks[j].second).norm();
      ++shared, ++i, ++j;
    }
  }
  const double turnover = 1.0 - static_cast<double>(shared) / static_cast<double>(std::max(tracks.size(), last_->tracks.size()));
  if (turnover >= options_.min_track_turnover) {
    std::snprintf(text, sizeof text, "track turnover %.0f %%", 100.0 * turnover);
    return accept(text);
  }
  if (shared > 0 && motion / static_cast<double>(shared) >= options_.min_mean_motion_px) {
    std::snprintf(text, sizeof text, "tracks moved %.1f px", motion / static_cast<double>(shared));
    return accept(text);
  }
  if (dt >= options_.max_interval_s) return accept("time since the last keyframe");
  decision.reason = "nothing new since the last keyframe";
  return decision;
}

}  // namespace nirslam
