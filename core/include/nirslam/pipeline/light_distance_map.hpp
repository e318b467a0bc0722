#pragma once
// Where the photometric calibration learns how far the co-located lamp is from what it tracks
// (issue 8): the calibration runs on a frame before the odometry has tracked it, so the
// distances come from the odometry's active points projected through a predicted pose of that
// frame (constant velocity from the last two tracked frames). A tracked patch takes the distance
// of a plane fitted to the points projected near it (their median where no plane fits), none
// where too few are near or they disagree (the calibration leaves such observations out rather
// than guess). Units are the odometry's: monocular scale cancels in the
// calibration's ratio (d_ref / d)^2 when the light sits at the camera centre, and nearly so for a
// lamp a few centimetres beside the lens.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/geometry/se3.hpp"

namespace nirslam {

struct LightDistanceMapOptions {
  double search_radius_px = 20.0;  // at 640 pixels wide; scaled with the image width
  int min_neighbours = 3;          // projected points within the radius for a distance
  // No distance where the neighbours disagree by more than this (median absolute deviation of
  // their log distances about their median; 0: no gate). What the calibration uses is a track's
  // distance ratio between frames, and where the neighbours scatter (a depth edge, points the
  // odometry has not converged) that ratio was off by more than 0.3 in log (35 % in distance,
  // 80 % in brightness) for 15-23 % of the tracked surface points in the co-lit parking and
  // tunnel runs, against 0.3-1 % with the gate (README, the pipeline co-lit table). It also
  // leaves out surfaces whose depth changes fast across the radius (a floor near the horizon),
  // where the light's missing cos(theta) changes most. Off by default: with it (0.05) the
  // calibration's halo factor improved but the 'illuminated' odometry got worse on 8 of the 12
  // bench sequences together with the plane fit (parking 50 / 100 W 0.06 -> 0.22 m; README,
  // "Illuminator correction").
  double max_log_spread = 0.0;
  // The distance where the neighbours allow it from a plane in inverse depth fitted to them
  // (1/z affine in the pixel, exact for a planar surface seen by a pinhole), evaluated at the
  // pixel itself, rather than their median (which takes the side most neighbours lie on).
  // Neighbours further than inlier_log_band (or 3 MADs, the larger) in log distance from their
  // median are left out of the fit; the result never leaves the inliers' inverse-depth range.
  bool fit_inverse_depth_plane = false;  // off: no gain measured in the pipeline, and parking 100 W got worse
  int min_fit_points = 6;
  double inlier_log_band = 0.1;
  // cos(theta) of the lamp's light on the surface, from a plane fitted to the neighbours: at
  // least this many of them, and flat enough (smallest / middle eigenvalue of their scatter).
  int min_plane_points = 8;
  double max_plane_flatness = 0.15;
  double min_cosine = 0.2;         // grazing light (or a wrong normal): no cosine
  // The normal from the inverse-depth plane fitted to them instead (it needs 6 neighbours
  // spread in both image directions, not 8 that pass the flatness test); without
  // fit_inverse_depth_plane the distance stays their median. On the simulated tunnel's walls the
  // 3-D scatter's plane gave cosines 0.07 times the truth (median), the inverse-depth plane's
  // 0.68 times (README "Illuminator correction", session 28).
  bool normal_from_inverse_depth_plane = false;
};

// The surface point on a camera ray (unit direction) at `light_distance` from the lamp at
// `light_offset_cam` (camera axes): the ray's far intersection with that sphere.
inline Eigen::Vector3d point_at_light_distance(const Eigen::Vector3d& direction, const Eigen::Vector3d& light_offset_cam,
                                               double light_distance) {
  const double along = direction.dot(light_offset_cam);
  return (along + std::sqrt(std::max(0.0, along * along - light_offset_cam.squaredNorm() + light_distance * light_distance))) *
         direction;
}

// What a pixel's neighbours say of the lamp's light on the surface there.
struct LightGeometry {
  double distance = 0.0;              // from the lamp to the surface
  std::optional<double> cosine;       // of the angle between the light's ray and the surface normal
  std::optional<Eigen::Vector3d> normal_cam;  // that normal (camera axes, facing the lamp), with the cosine
  // The fitted plane's normal (camera axes, facing the lamp) wherever the fit holds, also where
  // the light grazes it below min_cosine (TrackLightCosines holds it per track).
  std::optional<Eigen::Vector3d> plane_normal_cam;
};

class LightDistanceMap {
public:
  // `camera` is the model of the frames the calibration tracks (the source's own, distorted).
  explicit LightDistanceMap(const CameraModel& camera, LightDistanceMapOptions options = {});

  // Projects the points (world frame) into the camera at T_world_cam; the lamp sits at
  // light_offset_cam in the camera frame. Reuses its buffers: no allocation once warmed up.
  void build(std::span<const Eigen::Vector3d> points_world, const SE3& T_world_cam,
             const Eigen::Vector3d& light_offset_cam);
  void clear();

  // Distance from the lamp to the surface seen at `pixel` (the frame's own pixel coordinates),
  // the median over the projected points within the radius; std::nullopt where fewer are near.
  std::optional<double> light_distance(const Eigen::Vector2d& pixel) const;
  // The distance and, where a plane fits the neighbours, the cosine.
  std::optional<LightGeometry> light_geometry(const Eigen::Vector2d& pixel) const;

  std::size_t projected_points() const { return entries_.size(); }
  bool empty() const { return entries_.empty(); }

private:
  static constexpr std::size_t kMaxNeighbours = 64;  // enough for a robust median
  struct Entry {
    Eigen::Vector2f pixel;
    float log_light_distance;  // log |p_cam - light_offset|
    float inverse_depth;       // 1 / z_cam
    Eigen::Vector3f p_light;   // the point relative to the lamp, camera axes
  };
  // The neighbours of a pixel (at most kMaxNeighbours); their count.
  std::size_t neighbours(const Eigen::Vector2d& pixel, std::array<const Entry*, kMaxNeighbours>& out) const;
  std::optional<double> median_distance(const std::array<const Entry*, kMaxNeighbours>& near, std::size_t n) const;
  // The distance at `pixel` from the neighbours: the plane fit where it holds, else the median.
  // With plane_normal, also the fitted plane's unit normal (camera axes) where the fit held
  // (left untouched elsewhere).
  std::optional<double> distance_at(const Eigen::Vector2d& pixel, const std::array<const Entry*, kMaxNeighbours>& near,
                                    std::size_t n, Eigen::Vector3d* plane_normal = nullptr) const;
  int cell_of(int cx, int cy) const { return cy * cells_x_ + cx; }

  LightDistanceMapOptions options_;
  const CameraModel& camera_;
  double radius_px_;
  int cell_px_;
  int cells_x_;
  int cells_y_;
  Eigen::Vector3d light_offset_cam_ = Eigen::Vector3d::Zero();
  std::vector<Entry> entries_;          // sorted by cell
  std::vector<int> cell_start_;         // cells_x * cells_y + 1 offsets into entries_
  std::vector<Entry> unsorted_;
  std::vector<int> unsorted_cell_;
  std::vector<int> cursor_;
};

}  // namespace nirslam
