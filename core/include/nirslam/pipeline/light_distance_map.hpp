#pragma once
// Where the photometric calibration learns how far the co-located lamp is from what it tracks
// (issue 8): the calibration runs on a frame before the odometry has tracked it, so the
// distances come from the odometry's active points projected through a predicted pose of that
// frame (constant velocity from the last two tracked frames). A tracked patch takes the median
// distance of the points projected near it, none where too few are (the calibration leaves such
// observations out rather than guess). Units are the odometry's: monocular scale cancels in the
// calibration's ratio (d_ref / d)^2 when the light sits at the camera centre, and nearly so for a
// lamp a few centimetres beside the lens.

#include <array>
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
  // cos(theta) of the lamp's light on the surface, from a plane fitted to the neighbours: at
  // least this many of them, and flat enough (smallest / middle eigenvalue of their scatter).
  int min_plane_points = 8;
  double max_plane_flatness = 0.15;
  double min_cosine = 0.2;         // grazing light (or a wrong normal): no cosine
};

// What a pixel's neighbours say of the lamp's light on the surface there.
struct LightGeometry {
  double distance = 0.0;              // from the lamp to the surface
  std::optional<double> cosine;       // of the angle between the light's ray and the surface normal
  std::optional<Eigen::Vector3d> normal_cam;  // that normal (camera axes, facing the lamp), with the cosine
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
    Eigen::Vector3f p_light;   // the point relative to the lamp, camera axes
  };
  // The neighbours of a pixel (at most kMaxNeighbours); their count.
  std::size_t neighbours(const Eigen::Vector2d& pixel, std::array<const Entry*, kMaxNeighbours>& out) const;
  std::optional<double> median_distance(const std::array<const Entry*, kMaxNeighbours>& near, std::size_t n) const;
  int cell_of(int cx, int cy) const { return cy * cells_x_ + cx; }

  LightDistanceMapOptions options_;
  const CameraModel& camera_;
  double radius_px_;
  int cell_px_;
  int cells_x_;
  int cells_y_;
  std::vector<Entry> entries_;          // sorted by cell
  std::vector<int> cell_start_;         // cells_x * cells_y + 1 offsets into entries_
  std::vector<Entry> unsorted_;
  std::vector<int> unsorted_cell_;
  std::vector<int> cursor_;
};

}  // namespace nirslam
