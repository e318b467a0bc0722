#include "nirslam/odometry/surface_normals.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <Eigen/Eigenvalues>

namespace nirslam::odometry {

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
