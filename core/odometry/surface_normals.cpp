#include "nirslam/odometry/surface_normals.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <unordered_map>

#include <Eigen/Eigenvalues>

#include "nirslam/geometry/symmetric_eigenvalues.hpp"

namespace nirslam::odometry {
namespace {

// The normal (facing the camera) of the plane rho = a + b x + c y fitted to the neighbours.
std::optional<Eigen::Vector3d> inverse_depth_plane_normal(const LevelCamera& camera, const std::vector<WindowPoint>& points,
                                                          const std::vector<std::size_t>& near, const WindowPoint& at,
                                                          const SurfaceNormalOptions& options) {
  // Offsets from the point itself (conditioning), in normalised image coordinates.
  const Eigen::Vector2d origin = camera.unproject(at.pixel).head<2>();
  Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  double rho_sum = 0.0;
  for (std::size_t j : near) {
    const Eigen::Vector2d xy = camera.unproject(points[j].pixel).head<2>() - origin;
    const Eigen::Vector3d row(1.0, xy.x(), xy.y());
    normal_matrix.noalias() += row * row.transpose();
    rhs += row * points[j].inverse_depth;
    rho_sum += points[j].inverse_depth;
  }
  const double count = normal_matrix(0, 0);
  const Eigen::Vector2d mean = normal_matrix.block<2, 1>(1, 0) / count;
  const Eigen::Matrix2d spread = normal_matrix.block<2, 2>(1, 1) / count - mean * mean.transpose();
  const Eigen::Vector2d extent = symmetric_eigenvalues(spread);  // ascending
  if (!(extent[1] > 0.0) || extent[0] < options.min_spread_ratio * extent[1]) return std::nullopt;
  const Eigen::Vector3d plane = normal_matrix.ldlt().solve(rhs);
  if (!plane.allFinite()) return std::nullopt;
  double squared_residual = 0.0;
  for (std::size_t j : near) {
    const Eigen::Vector2d xy = camera.unproject(points[j].pixel).head<2>() - origin;
    const double r = points[j].inverse_depth - (plane[0] + plane[1] * xy.x() + plane[2] * xy.y());
    squared_residual += r * r;
  }
  const double mean_rho = rho_sum / count;
  if (!(mean_rho > 0.0) || std::sqrt(squared_residual / count) > options.max_relative_residual * mean_rho) return std::nullopt;
  // rho = a' + b x + c y in absolute coordinates (a' = a - b x0 - c y0) is the plane
  // (b, c, a') . p = 1 for p = (x, y, 1) / rho.
  Eigen::Vector3d n(plane[1], plane[2], plane[0] - plane[1] * origin.x() - plane[2] * origin.y());
  if (!(n.norm() > 0.0)) return std::nullopt;
  n.normalize();
  if (n.dot(camera.unproject(at.pixel)) > 0.0) n = -n;  // towards the camera
  return n;
}

}  // namespace

void estimate_surface_normals(const LevelCamera& camera, std::vector<WindowPoint>& points,
                              const SurfaceNormalOptions& options) {
  // The neighbourhood follows the points' density: radius_spacings mean spacings.
  const double spacing = std::sqrt(static_cast<double>(camera.width) * camera.height /
                                   static_cast<double>(std::max<std::size_t>(points.size(), 1)));
  const double radius = std::max(3.0, options.radius_spacings * spacing);
  const double cell = radius;
  const int columns = static_cast<int>(std::ceil(camera.width / cell)) + 1;
  std::vector<Eigen::Vector3d> X(points.size());
  std::unordered_map<int, std::vector<std::size_t>> grid;
  for (std::size_t i = 0; i < points.size(); ++i) {
    points[i].normal.reset();
    if (points[i].inverse_depth < 1e-3) continue;  // too far for a depth-based plane
    X[i] = camera.unproject(points[i].pixel) / points[i].inverse_depth;
    const int cx = static_cast<int>(points[i].pixel.x() / cell);
    const int cy = static_cast<int>(points[i].pixel.y() / cell);
    grid[cy * columns + cx].push_back(i);
  }
  std::vector<std::size_t> near;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (points[i].inverse_depth < 1e-3) continue;
    const int cx = static_cast<int>(points[i].pixel.x() / cell);
    const int cy = static_cast<int>(points[i].pixel.y() / cell);
    near.clear();
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const auto it = grid.find((cy + dy) * columns + cx + dx);
        if (it == grid.end()) continue;
        for (std::size_t j : it->second) {
          if ((points[j].pixel - points[i].pixel).squaredNorm() > radius * radius) continue;
          if (std::abs(X[j].z() - X[i].z()) > options.max_relative_depth_gap * X[i].z()) continue;
          near.push_back(j);
        }
      }
    }
    if (static_cast<int>(near.size()) < options.min_neighbours) continue;
    if (options.fit == SurfaceNormalFit::InverseDepthPlane) {
      if (const auto n = inverse_depth_plane_normal(camera, points, near, points[i], options)) points[i].normal = *n;
      continue;
    }
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t j : near) mean += X[j];
    mean /= static_cast<double>(near.size());
    Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
    for (std::size_t j : near) spread += (X[j] - mean) * (X[j] - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(spread);
    const Eigen::Vector3d values = eig.eigenvalues();  // ascending
    // A plane: thin across (smallest spread well below the middle one) and spread in two
    // directions (points along one image edge leave the plane's tilt about that line open).
    if (!(values[1] > 0.0) || values[0] > options.max_flatness * values[1] || values[1] < options.min_spread_ratio * values[2])
      continue;
    Eigen::Vector3d n = eig.eigenvectors().col(0).normalized();
    if (n.dot(X[i]) > 0.0) n = -n;  // towards the camera
    points[i].normal = n;
  }
}

}  // namespace nirslam::odometry

namespace nirslam {

std::string_view to_string(SurfaceNormalFit fit) {
  switch (fit) {
    case SurfaceNormalFit::Spread: return "spread";
    case SurfaceNormalFit::InverseDepthPlane: return "inverse-depth-plane";
  }
  return "?";
}

std::optional<SurfaceNormalFit> surface_normal_fit_from_string(std::string_view text) {
  for (const SurfaceNormalFit fit : {SurfaceNormalFit::Spread, SurfaceNormalFit::InverseDepthPlane})
    if (text == to_string(fit)) return fit;
  return std::nullopt;
}

}  // namespace nirslam
