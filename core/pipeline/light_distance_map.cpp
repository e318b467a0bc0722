#include "nirslam/pipeline/light_distance_map.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "nirslam/geometry/symmetric_eigenvalues.hpp"

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
  light_offset_cam_ = light_offset_cam;
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
    unsorted_.push_back({pixel->cast<float>(), static_cast<float>(std::log(p_light.norm())),
                         static_cast<float>(1.0 / p_cam.z()), p_light.cast<float>()});
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

std::optional<double> LightDistanceMap::distance_at(const Eigen::Vector2d& pixel,
                                                    const std::array<const Entry*, kMaxNeighbours>& near,
                                                    std::size_t n, Eigen::Vector3d* plane_normal) const {
  const std::optional<double> median = median_distance(near, n);
  // The plane is fitted for its distance, or for its normal alone (the median stays the distance).
  const bool fit = options_.fit_inverse_depth_plane || (plane_normal != nullptr && options_.normal_from_inverse_depth_plane);
  // Neither the gate nor the fit (the defaults): the median is the answer, no spread needed.
  if (!median || (options_.max_log_spread <= 0.0 && !fit)) return median;
  // Inliers: within the band (or 3 MADs) of the median in log distance.
  const double log_median = std::log(*median);
  std::array<float, kMaxNeighbours> deviations{};
  for (std::size_t i = 0; i < n; ++i) deviations[i] = std::abs(near[i]->log_light_distance - static_cast<float>(log_median));
  const auto middle = deviations.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(deviations.begin(), middle, deviations.begin() + static_cast<std::ptrdiff_t>(n));
  if (options_.max_log_spread > 0.0 && static_cast<double>(*middle) > options_.max_log_spread) return std::nullopt;
  if (!fit || static_cast<int>(n) < options_.min_fit_points) return median;
  const double band = std::max(options_.inlier_log_band, 3.0 * 1.4826 * static_cast<double>(*middle));
  // Least squares for 1/z = a + b du + c dv, offsets in units of the radius (conditioning).
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  float low = std::numeric_limits<float>::max(), high = 0.0f;
  int inliers = 0;
  const double scale = 1.0 / radius_px_;
  for (std::size_t i = 0; i < n; ++i) {
    const Entry& e = *near[i];
    if (std::abs(static_cast<double>(e.log_light_distance) - log_median) > band) continue;
    const Eigen::Vector3d row(1.0, (e.pixel.x() - pixel.x()) * scale, (e.pixel.y() - pixel.y()) * scale);
    normal.noalias() += row * row.transpose();
    rhs += row * static_cast<double>(e.inverse_depth);
    low = std::min(low, e.inverse_depth);
    high = std::max(high, e.inverse_depth);
    ++inliers;
  }
  if (inliers < options_.min_fit_points) return median;
  // The neighbours must spread in both image directions (points along a line leave the tilt
  // across it open): the pixel offsets' scatter about their mean, smallest eigenvalue.
  const double count = normal(0, 0);
  const Eigen::Vector2d mean = normal.block<2, 1>(1, 0) / count;
  const Eigen::Matrix2d spread = normal.block<2, 2>(1, 1) / count - mean * mean.transpose();
  if (!(symmetric_eigenvalues(spread)[0] > 0.02)) return median;  // (0.14 radius)^2
  const Eigen::Vector3d plane = normal.ldlt().solve(rhs);
  // At the pixel; never beyond the inliers' own inverse depths (no extrapolation off an edge).
  const double inverse_depth = std::clamp(plane[0], static_cast<double>(low), static_cast<double>(high));
  const auto ray = camera_.unproject(pixel);
  if (!ray || !(inverse_depth > 0.0) || !std::isfinite(inverse_depth)) return median;
  if (plane_normal != nullptr) {
    // The same plane in 3-D: with (x, y) the normalised image coordinates (ray = (x, y, 1)),
    // 1/z = alpha + beta x + gamma y is the plane (beta, gamma, alpha) . p = 1. The pixel
    // gradient (b, c) / radius maps to (beta, gamma) through the inverse transpose of
    // d(x, y)/d(u, v), taken by differences of unproject (any camera model).
    const auto ray_u = camera_.unproject(pixel + Eigen::Vector2d(1.0, 0.0));
    const auto ray_v = camera_.unproject(pixel + Eigen::Vector2d(0.0, 1.0));
    if (ray_u && ray_v) {
      Eigen::Matrix2d d_xy_d_uv;
      d_xy_d_uv.col(0) = (*ray_u - *ray).head<2>();
      d_xy_d_uv.col(1) = (*ray_v - *ray).head<2>();
      const Eigen::Vector2d slope = d_xy_d_uv.transpose().inverse() * (plane.tail<2>() * scale);
      const Eigen::Vector3d plane_n(slope.x(), slope.y(), plane[0] - slope.dot(ray->head<2>()));
      if (plane_n.allFinite() && plane_n.norm() > 0.0) *plane_normal = plane_n.normalized();
    }
  }
  if (!options_.fit_inverse_depth_plane) return median;
  return (*ray / inverse_depth - light_offset_cam_).norm();
}

std::optional<double> LightDistanceMap::light_distance(const Eigen::Vector2d& pixel) const {
  std::array<const Entry*, kMaxNeighbours> near{};
  return distance_at(pixel, near, neighbours(pixel, near));
}

std::optional<LightGeometry> LightDistanceMap::light_geometry(const Eigen::Vector2d& pixel) const {
  std::array<const Entry*, kMaxNeighbours> near{};
  const std::size_t n = neighbours(pixel, near);
  Eigen::Vector3d fitted_normal = Eigen::Vector3d::Zero();
  const std::optional<double> distance = distance_at(pixel, near, n, &fitted_normal);
  if (!distance) return std::nullopt;
  LightGeometry geometry;
  geometry.distance = *distance;
  if (options_.normal_from_inverse_depth_plane) {
    if (fitted_normal.isZero()) return geometry;
    const auto ray = camera_.unproject(pixel);
    if (!ray) return geometry;
    // The surface point on the ray at that distance from the lamp, and the light's incidence.
    const Eigen::Vector3d to_lamp =
        (light_offset_cam_ - point_at_light_distance(ray->normalized(), light_offset_cam_, *distance)).normalized();
    double cosine = fitted_normal.dot(to_lamp);
    Eigen::Vector3d normal = fitted_normal;
    if (cosine < 0.0) {
      cosine = -cosine;
      normal = -normal;
    }
    geometry.plane_normal_cam = normal;
    if (cosine >= options_.min_cosine && cosine <= 1.0) {
      geometry.cosine = cosine;
      geometry.normal_cam = normal;
    }
    return geometry;
  }
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
  geometry.plane_normal_cam = normal.cast<double>();
  if (cosine >= static_cast<float>(options_.min_cosine)) {
    geometry.cosine = static_cast<double>(cosine);
    geometry.normal_cam = normal.cast<double>();
  }
  return geometry;
}

}  // namespace nirslam
