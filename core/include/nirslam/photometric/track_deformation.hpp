#pragma once

// How the surface around each tracked point has deformed in the image since the track was born
// (issue 6: the photometric calibration's observations follow the surface, not a fixed window).
//
// A fixed 9 x 9 pixel window around a tracked point covers less and less of the surface as the
// camera approaches it (and more as it recedes), and the features the tracker picks (corners:
// crossings of dark joints, spots) are not like their surroundings, so the window's mean radiance
// changes with the track's magnification even where the radiance at the point itself is constant
// (the simulated tunnel: the window's rendered radiance fell 0.5 % per 10 frames of a track's life,
// the radiance at the tracked point stayed within 0.1 %; README "Photometric calibration
// accuracy"). Sampled at position + A o instead (o the pixel offsets at birth), a patch stays on
// the same surface, where A is the local 2 x 2 map the image has undergone around the track.
//
// A is fitted to the neighbouring tracks: each track keeps its nearest tracks (max_neighbours
// within neighbour_radius_px) and their offsets at a REFERENCE frame; in a later frame A_rel is
// the least-squares 2 x 2 map from those offsets to the current ones (when some neighbour is more
// than 1 px and three median residuals off, e.g. across a depth edge: over the neighbours that
// agree with the best two-neighbour model instead), and A = A_rel A_reference, A_reference the
// deformation from birth to the reference.
// When too many reference neighbours have been lost, the track takes new ones in the current
// frame (while A is still determined there), so the chain from birth outlives its neighbours.
// The tracker loses many tracks within a few frames of their birth (simulated room at 320 x 240:
// 46 new tracks a frame for 117 tracked, so whole neighbour sets go between two frames):
// established neighbours (established_age frames old) are taken first, and when the reference's
// survivors no longer determine A_rel, the step since the last frame is fitted to the tracks near
// it in both frames (A = A_step A_last) and the track takes new neighbours there. Even so, with
// 40 px 11 % of the room's track-frames broke the chain (1897 of 17499, first pass), with 60 px
// 5 % (892; the tunnel 10 % -> 2 %), hence 60 px.
// When neither determines A (too few neighbours, all along a line) or A leaves
// [1/max_area_change, max_area_change] in area, the chain breaks: the track starts a new SURFACE
// (TrackObservation::surface + 1) with A = I. Consumers compare a track's observations only
// within one surface: the exposure estimator re-anchors the track, and the back end takes each
// (track, surface) as its own points.
//
// One estimate shared by the front end's exposure estimate and the back end's keyframe
// observations (the tracker runs it when PhotometricTrackerOptions::estimate_deformation is set).
// Cost: one small least-squares fit per track and frame; new neighbours are searched over all
// tracks only when a track is born or re-referenced.

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace nirslam {

struct TrackedFrame;

struct TrackDeformationOptions {
  double neighbour_radius_px = 60.0;     // neighbours within this distance at the reference (see above) ...
  int max_neighbours = 12;               // ... the nearest this many of them
  int min_neighbours = 4;                // inliers needed for a fit
  double min_neighbour_spread_px = 6.0;  // rms spread of their offsets along the weaker axis
  double max_area_change = 4.0;          // |det A| outside [1/this, this]: a new surface
  // New neighbours (a new reference) once fewer than this fraction of the reference's are still
  // tracked, or fewer than min_neighbours + 2: well before the fit loses its support.
  double refresh_fraction = 0.75;
  // Neighbours at least this many frames old are taken first (younger ones fill up the set).
  int established_age = 3;
};

class TrackDeformation {
public:
  explicit TrackDeformation(TrackDeformationOptions options = {});

  // Sets every track's `deformation` (A since its surface began) and `surface`, and
  // tracked.deformation_estimated. Tracks are matched to earlier frames by id; tracks not in
  // this frame are forgotten.
  void update(TrackedFrame& tracked);
  void reset();
  const TrackDeformationOptions& options() const { return options_; }

private:
  struct Neighbour {
    std::int64_t id = 0;
    Eigen::Vector2d offset = Eigen::Vector2d::Zero();  // its position minus the track's, at the reference
  };
  struct State {
    std::vector<Neighbour> neighbours;
    Eigen::Matrix2d at_reference = Eigen::Matrix2d::Identity();  // A from the surface's start to the reference
    Eigen::Matrix2d last = Eigen::Matrix2d::Identity();          // A in the last frame
    std::int32_t surface = 0;
  };
  // The nearest tracks around track `index`, their offsets now (the new reference).
  void choose_neighbours(const TrackedFrame& tracked, std::size_t index, State& state);
  // A_rel from the reference to now and how many reference neighbours are still tracked;
  // nullopt when they do not determine it.
  std::optional<Eigen::Matrix2d> fit(const TrackedFrame& tracked, std::size_t index, const State& state, int& surviving);
  // A_step from the last frame to now, from the tracks near it in both (the fallback above).
  std::optional<Eigen::Matrix2d> fit_since_last_frame(const TrackedFrame& tracked, std::size_t index);
  // The robust fit over pairs_ (see the header).
  std::optional<Eigen::Matrix2d> fit_pairs();

  TrackDeformationOptions options_;
  std::unordered_map<std::int64_t, State> states_;
  std::unordered_map<std::int64_t, std::size_t> index_;  // id -> index in tracked.tracks, this frame
  std::unordered_map<std::int64_t, Eigen::Vector2d> previous_;  // id -> position, the last frame
  std::vector<std::pair<double, std::size_t>> nearest_;  // (squared distance, index)
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> pairs_;  // (offset at reference, now)
  std::vector<double> residuals_, sorted_;
};

}  // namespace nirslam
