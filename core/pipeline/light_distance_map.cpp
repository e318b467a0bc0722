#include "nirslam/pipeline/light_distance_map.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace nirslam {

LightDistanceMap::LightDistanceMap(const CameraModel& camera, LightDistanceMapOptions options)
    : options_(options), camera_(camera) {
  radius_px_ = std::max(1.0, options_.search_radius_px * camera_.width() / 640.0);
  cell_px_ = std::max(1, static_cast<int>(std::ceil(radius_px_)));
  cells_x_ = (camera_.width() + cell_px_ - 1) / cell_px_;
  cells_y_ = (camera_.height() + cell_px_ - 1) / cell_px_;
  cell_start_.assign(static_cast<std::size_t>(cells_x_ * cells_y_ + 1), 0);
}

void LightDistanceMap::clear() {
  entries_.clear();
  std::fill(cell_start_.begin(), cell_start_.end(), 0);
}

void LightDistanceMap::build(std::span<const Eigen::Vector3d> points_world, const SE3& T_world_cam,
                             const Eigen::Vector3d& light_offset_cam) {
  const SE3 T_cam_world = T_world_cam.inverse();
  unsorted_.clear();
  unsorted_cell_.clear();
  for (const Eigen::Vector3d& p_world : points_world) {
    const Eigen::Vector3d p_cam = T_cam_world * p_world;
    if (!(p_cam.z() > 0.0)) continue;
    const auto pixel = camera_.project(p_cam);
    if (!pixel || !camera_.contains(*pixel)) continue;
    const int cx = std::clamp(static_cast<int>(pixel->x()) / cell_px_, 0, cells_x_ - 1);
    const int cy = std::clamp(static_cast<int>(pixel->y()) / cell_px_, 0, cells_y_ - 1);
    const Eigen::Vector3d p_light = p_cam - light_offset_cam;
    unsorted_.push_back({pixel->cast<float>(), static_cast<float>(std::log(p_light.norm())), p_light.cast<float>()});
    unsorted_cell_.push_back(cell_of(cx, cy));
  }
  // Counting sort by cell: a query then reads a 3x3 block of cells.
  std::fill(cell_start_.begin(), cell_start_.end(), 0);
  for (const int c : unsorted_cell_) ++cell_start_[static_cast<std::size_t>(c) + 1];
  for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  entries_.resize(unsorted_.size());
  cursor_.assign(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t i = 0; i < unsorted_.size(); ++i) {
    const auto c = static_cast<std::size_t>(unsorted_cell_[i]);
    entries_[static_cast<std::size_t>(cursor_[c]++)] = unsorted_[i];
  }
}

std::size_t LightDistanceMap::neighbours(const Eigen::Vector2d& pixel, std::array<const Entry*, kMaxNeighbours>& out) const {
  if (entries_.empty() || !camera_.contains(pixel)) return 0;
  const int cx = std::clamp(static_cast<int>(pixel.x()) / cell_px_, 0, cells_x_ - 1);
  const int cy = std::clamp(static_cast<int>(pixel.y()) / cell_px_, 0, cells_y_ - 1);
  const float r2_max = static_cast<float>(radius_px_ * radius_px_);
  const Eigen::Vector2f p = pixel.cast<float>();
  std::size_t n = 0;
  for (int y = std::max(0, cy - 1); y <= std::min(cells_y_ - 1, cy + 1); ++y)
    for (int x = std::max(0, cx - 1); x <= std::min(cells_x_ - 1, cx + 1); ++x) {
      const int c = cell_of(x, y);
      for (int i = cell_start_[static_cast<std::size_t>(c)]; i < cell_start_[static_cast<std::size_t>(c) + 1] && n < out.size(); ++i) {
        const Entry& e = entries_[static_cast<std::size_t>(i)];
        if ((e.pixel - p).squaredNorm() <= r2_max) out[n++] = &e;
      }
    }
  return n;
}

std::optional<double> LightDistanceMap::median_distance(const std::array<const Entry*, kMaxNeighbours>& near,
                                                       std::size_t n) const {
  if (static_cast<int>(n) < options_.min_neighbours) return std::nullopt;
  // The median of the neighbours' log distances: a single point's depth is noisy (a window's
  // active points scatter by 10-20 % in depth at 320x240), and on a depth edge the median takes
  // the side most neighbours lie on instead of a blend that lies on neither.
  std::array<float, kMaxNeighbours> log_distances{};
  for (std::size_t i = 0; i < n; ++i) log_distances[i] = near[i]->log_light_distance;
  const auto middle = log_distances.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(log_distances.begin(), middle, log_distances.begin() + static_cast<std::ptrdiff_t>(n));
  return std::exp(static_cast<double>(*middle));
}

std::optional<double> LightDistanceMap::light_distance(const Eigen::Vector2d& pixel) const {
  std::array<const Entry*, kMaxNeighbours> near{};
  return median_distance(near, neighbours(pixel, near));
}

std::optional<LightGeometry> LightDistanceMap::light_geometry(const Eigen::Vector2d& pixel) const {
  std::array<const Entry*, kMaxNeighbours> near{};
  const std::size_t n = neighbours(pixel, near);
  const std::optional<double> distance = median_distance(near, n);
  if (!distance) return std::nullopt;
  LightGeometry geometry;
  geometry.distance = *distance;
  if (static_cast<int>(n) < options_.min_plane_points) return geometry;
  // Plane through the neighbours (relative to the lamp: the offset cancels in the scatter).
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  for (std::size_t i = 0; i < n; ++i) centroid += near[i]->p_light;
  centroid /= static_cast<float>(n);
  Eigen::Matrix3f scatter = Eigen::Matrix3f::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f d = near[i]->p_light - centroid;
    scatter.noalias() += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eigen(scatter);
  const Eigen::Vector3f& values = eigen.eigenvalues();  // ascending
  if (!(values[1] > 0.0f) || values[0] > static_cast<float>(options_.max_plane_flatness) * values[1]) return geometry;
  Eigen::Vector3f normal = eigen.eigenvectors().col(0);
  // The lamp lights the side facing it: cos = n . (direction from the surface to the lamp).
  const Eigen::Vector3f to_lamp = -centroid.normalized();
  float cosine = normal.dot(to_lamp);
  if (cosine < 0.0f) {
    cosine = -cosine;
    normal = -normal;
  }
  if (cosine >= static_cast<float>(options_.min_cosine)) {
    geometry.cosine = static_cast<double>(cosine);
    geometry.normal_cam = normal.cast<double>();
  }
  return geometry;
}

}  // namespace nirslam
