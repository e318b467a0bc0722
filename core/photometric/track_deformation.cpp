#include "nirslam/photometric/track_deformation.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>

#include <Eigen/LU>

#include "nirslam/geometry/symmetric_eigenvalues.hpp"
#include "nirslam/photometric/photometric_tracker.hpp"

namespace nirslam {

TrackDeformation::TrackDeformation(TrackDeformationOptions options) : options_(options) {
  if (!(options_.neighbour_radius_px > 0.0) || options_.max_neighbours < 1 || options_.min_neighbours < 2 ||
      !(options_.max_area_change > 1.0) || !(options_.refresh_fraction >= 0.0 && options_.refresh_fraction <= 1.0))
    throw std::invalid_argument("track deformation: bad options");
}

void TrackDeformation::reset() {
  states_.clear();
  previous_.clear();
}

void TrackDeformation::choose_neighbours(const TrackedFrame& tracked, std::size_t index, State& state) {
  // Any track near it (new or old: only their positions are used).
  const Eigen::Vector2d& centre = tracked.tracks[index].position;
  const double radius_sq = options_.neighbour_radius_px * options_.neighbour_radius_px;
  nearest_.clear();
  for (std::size_t j = 0; j < tracked.tracks.size(); ++j) {
    const double d2 = (tracked.tracks[j].position - centre).squaredNorm();
    // Established tracks first: most new tracks are lost within a few frames, and a neighbour
    // set that goes with them leaves A undetermined (the chain breaks).
    const double young = tracked.tracks[j].age < options_.established_age ? 4.0 * radius_sq : 0.0;
    if (j != index && d2 <= radius_sq) nearest_.emplace_back(d2 + young, j);
  }
  const std::size_t keep = std::min(nearest_.size(), static_cast<std::size_t>(options_.max_neighbours));
  std::partial_sort(nearest_.begin(), nearest_.begin() + static_cast<std::ptrdiff_t>(keep), nearest_.end());
  state.neighbours.clear();
  state.neighbours.reserve(keep);
  for (std::size_t k = 0; k < keep; ++k) {
    const TrackObservation& n = tracked.tracks[nearest_[k].second];
    state.neighbours.push_back(Neighbour{n.id, n.position - centre});
  }
}

std::optional<Eigen::Matrix2d> TrackDeformation::fit(const TrackedFrame& tracked, std::size_t index, const State& state,
                                                     int& surviving) {
  const Eigen::Vector2d& centre = tracked.tracks[index].position;
  pairs_.clear();
  for (const Neighbour& n : state.neighbours) {
    const auto it = index_.find(n.id);
    if (it != index_.end()) pairs_.emplace_back(n.offset, tracked.tracks[it->second].position - centre);
  }
  surviving = static_cast<int>(pairs_.size());
  return fit_pairs();
}

std::optional<Eigen::Matrix2d> TrackDeformation::fit_since_last_frame(const TrackedFrame& tracked, std::size_t index) {
  const auto self = previous_.find(tracked.tracks[index].id);
  if (self == previous_.end()) return std::nullopt;
  // Every track near it in both frames, nearest (in the last frame) first.
  const Eigen::Vector2d& centre = tracked.tracks[index].position;
  const double radius_sq = options_.neighbour_radius_px * options_.neighbour_radius_px;
  nearest_.clear();
  for (std::size_t j = 0; j < tracked.tracks.size(); ++j) {
    if (j == index) continue;
    const auto before = previous_.find(tracked.tracks[j].id);
    if (before == previous_.end()) continue;
    const double d2 = (before->second - self->second).squaredNorm();
    if (d2 <= radius_sq) nearest_.emplace_back(d2, j);
  }
  const std::size_t keep = std::min(nearest_.size(), static_cast<std::size_t>(options_.max_neighbours));
  std::partial_sort(nearest_.begin(), nearest_.begin() + static_cast<std::ptrdiff_t>(keep), nearest_.end());
  pairs_.clear();
  for (std::size_t k = 0; k < keep; ++k) {
    const TrackObservation& n = tracked.tracks[nearest_[k].second];
    pairs_.emplace_back(previous_.at(n.id) - self->second, n.position - centre);
  }
  return fit_pairs();
}

std::optional<Eigen::Matrix2d> TrackDeformation::fit_pairs() {
  const std::optional<Eigen::Matrix2d> undetermined;
  if (static_cast<int>(pairs_.size()) < options_.min_neighbours) return undetermined;
  // Least squares A = (sum now ref^T) (sum ref ref^T)^-1 over all neighbours when none is more
  // than 1 px off it (the common case), else over those within max(1 px, 3 median residuals) of
  // the model that most neighbours agree with (below).
  const auto residuals_under = [&](const Eigen::Matrix2d& model) {
    residuals_.clear();
    for (const auto& [before, now] : pairs_) residuals_.push_back((now - model * before).norm());
  };
  const auto threshold_of = [&]() {
    sorted_ = residuals_;
    const auto middle = sorted_.begin() + static_cast<std::ptrdiff_t>(sorted_.size() / 2);
    std::nth_element(sorted_.begin(), middle, sorted_.end());
    return std::max(1.0, 3.0 * *middle);
  };
  const auto least_squares = [&](double threshold, Eigen::Matrix2d& model, int& used) {
    Eigen::Matrix2d cross = Eigen::Matrix2d::Zero(), spread = Eigen::Matrix2d::Zero();
    used = 0;
    for (std::size_t j = 0; j < pairs_.size(); ++j) {
      if (residuals_[j] > threshold) continue;
      cross += pairs_[j].second * pairs_[j].first.transpose();
      spread += pairs_[j].first * pairs_[j].first.transpose();
      ++used;
    }
    if (used < options_.min_neighbours) return false;
    // Neighbours along one line (an edge, a row of corners) leave A across it open.
    if (!(symmetric_eigenvalues(spread / used)(0) >= options_.min_neighbour_spread_px * options_.min_neighbour_spread_px)) return false;
    model = cross * spread.inverse();
    return true;
  };
  Eigen::Matrix2d a = Eigen::Matrix2d::Identity();
  int used = 0;
  residuals_.assign(pairs_.size(), 0.0);
  if (!least_squares(0.0, a, used)) return undetermined;
  residuals_under(a);
  if (*std::max_element(residuals_.begin(), residuals_.end()) > 1.0) {
    // A neighbour across a depth edge drags a fit of a few neighbours so far that a threshold on
    // its residuals keeps it (7 neighbours, one 8 px off: the others 0.7-2.4 px, the outlier 4.1).
    // Instead the model of the two neighbours (A is determined by two offsets) that most others
    // agree with to 1 px, then least squares over its inliers.
    Eigen::Matrix2d best = a;
    int best_count = -1;
    for (std::size_t i = 0; i < pairs_.size(); ++i)
      for (std::size_t j = i + 1; j < pairs_.size(); ++j) {
        Eigen::Matrix2d before, now;
        before << pairs_[i].first, pairs_[j].first;
        now << pairs_[i].second, pairs_[j].second;
        const double det = before.determinant();
        // Two offsets at a right angle of 10 px each give det 100: well below, the model is noise.
        if (!(std::abs(det) >= 25.0)) continue;
        const Eigen::Matrix2d model = now * before.inverse();
        int count = 0;
        for (const auto& [b, n] : pairs_) count += (n - model * b).norm() <= 1.0;
        if (count > best_count) best_count = count, best = model;
      }
    residuals_under(best);
    if (!least_squares(threshold_of(), a, used)) return undetermined;
  }
  if (!a.allFinite()) return undetermined;
  return a;
}

void TrackDeformation::update(TrackedFrame& tracked) {
  index_.clear();
  for (std::size_t i = 0; i < tracked.tracks.size(); ++i) index_.emplace(tracked.tracks[i].id, i);
  for (auto it = states_.begin(); it != states_.end();) it = index_.count(it->first) ? std::next(it) : states_.erase(it);
  const auto area_ok = [&](const Eigen::Matrix2d& a) {
    const double area = std::abs(a.determinant());
    return area >= 1.0 / options_.max_area_change && area <= options_.max_area_change;
  };
  for (std::size_t i = 0; i < tracked.tracks.size(); ++i) {
    TrackObservation& track = tracked.tracks[i];
    const auto [it, born] = states_.try_emplace(track.id);
    State& state = it->second;
    Eigen::Matrix2d now = Eigen::Matrix2d::Identity();
    if (born) {
      choose_neighbours(tracked, i, state);
    } else {
      int surviving = 0;
      bool stepped = false;
      std::optional<Eigen::Matrix2d> relative = fit(tracked, i, state, surviving);
      if (relative) {
        now = *relative * state.at_reference;
      } else if ((relative = fit_since_last_frame(tracked, i))) {
        // The reference's neighbours are gone (many tracks live only a few frames): the step
        // since the last frame from the tracks near it in both, and new neighbours here.
        now = *relative * state.last;
        stepped = true;
      }
      if (!relative || !area_ok(now)) {
        // The chain from the surface's start is broken: what follows is a new surface.
        ++state.surface;
        state.at_reference.setIdentity();
        now.setIdentity();
        choose_neighbours(tracked, i, state);
      } else if (stepped) {
        state.at_reference = now;
        choose_neighbours(tracked, i, state);
      } else if (surviving < static_cast<int>(state.neighbours.size()) &&
                 (surviving < options_.min_neighbours + 2 ||
                  surviving < options_.refresh_fraction * static_cast<double>(state.neighbours.size()))) {
        // Still determined here: carry A over to new neighbours before the old ones run out (only
        // after a loss: a track born with few neighbours would otherwise re-reference every frame,
        // which chains frame-to-frame fits into a random walk).
        state.at_reference = now;
        choose_neighbours(tracked, i, state);
      }
    }
    track.deformation = now;
    track.surface = state.surface;
    state.last = now;
  }
  previous_.clear();
  for (const TrackObservation& t : tracked.tracks) previous_.emplace(t.id, t.position);
  tracked.deformation_estimated = true;
}

}  // namespace nirslam
