#include "nirslam/eval/alignment.hpp"

#include <algorithm>
#include <stdexcept>

#include <Eigen/SVD>

namespace nirslam {

std::string to_string(AlignmentMode mode) {
  switch (mode) {
    case AlignmentMode::None: return "none";
    case AlignmentMode::SE3: return "se3";
    case AlignmentMode::Sim3: return "sim3";
  }
  return "unknown";
}

std::optional<AlignmentMode> alignment_mode_from_string(const std::string& name) {
  for (const AlignmentMode m : {AlignmentMode::None, AlignmentMode::SE3, AlignmentMode::Sim3})
    if (name == to_string(m)) return m;
  return std::nullopt;
}

SE3 Sim3Transform::apply(const SE3& T_world_cam) const {
  return SE3(Eigen::Matrix3d(rotation * T_world_cam.rotation_matrix()), Eigen::Vector3d(apply(T_world_cam.translation())));
}

Sim3Transform Sim3Transform::inverse() const {
  Sim3Transform inv;
  inv.rotation = rotation.transpose();
  inv.scale = 1.0 / scale;
  inv.translation = -(inv.rotation * translation) / scale;
  return inv;
}

std::optional<double> AlignmentResult::scale_error_percent() const {
  if (!sim3_scale) return std::nullopt;
  return (1.0 / *sim3_scale - 1.0) * 100.0;
}

namespace {

Eigen::Vector3d mean_of(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : points) sum += p;
  return sum / static_cast<double>(points.size());
}

}  // namespace

std::optional<std::string> alignment_degeneracy(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 3)
    return "only " + std::to_string(points.size()) + " point(s); an alignment needs at least 3 that are not on one line";
  const Eigen::Vector3d mean = mean_of(points);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  double extent = 0.0;
  for (const auto& p : points) {
    scatter += (p - mean) * (p - mean).transpose();
    extent = std::max(extent, p.cwiseAbs().maxCoeff());
  }
  // Singular values of the centred points (square roots of the scatter's eigenvalues).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(scatter);
  const Eigen::Vector3d spread = svd.singularValues().cwiseMax(0.0).cwiseSqrt();
  if (spread(0) <= 1e-12 * std::max(1.0, extent))
    return "all " + std::to_string(points.size()) + " points are at one place; an alignment needs points spread out";
  if (spread(1) <= 1e-6 * spread(0))
    return "all " + std::to_string(points.size()) +
           " points lie on one straight line: the rotation about that line is undetermined (3 non-collinear points "
           "are needed)";
  return std::nullopt;
}

Sim3Transform umeyama_alignment(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                                bool with_scale) {
  if (source.size() != target.size())
    throw std::invalid_argument("umeyama_alignment: " + std::to_string(source.size()) + " source and " +
                                std::to_string(target.size()) + " target points");
  if (const auto reason = alignment_degeneracy(source)) throw std::invalid_argument("estimate: " + *reason);
  if (const auto reason = alignment_degeneracy(target)) throw std::invalid_argument("ground truth: " + *reason);

  const double n = static_cast<double>(source.size());
  const Eigen::Vector3d mu_source = mean_of(source);
  const Eigen::Vector3d mu_target = mean_of(target);
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // Sigma_xy of Umeyama's Eq. (38)
  double source_variance = 0.0;                           // sigma_x^2, Eq. (36)
  for (std::size_t i = 0; i < source.size(); ++i) {
    const Eigen::Vector3d x = source[i] - mu_source;
    covariance += (target[i] - mu_target) * x.transpose();
    source_variance += x.squaredNorm();
  }
  covariance /= n;
  source_variance /= n;

  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;  // Eq. (43): no reflection

  Sim3Transform result;
  result.rotation = svd.matrixU() * S * svd.matrixV().transpose();                              // Eq. (40)
  result.scale = with_scale ? (svd.singularValues().asDiagonal() * S).trace() / source_variance : 1.0;  // Eq. (42)
  result.translation = mu_target - result.scale * result.rotation * mu_source;                  // Eq. (41)
  return result;
}

AlignmentResult align_positions(const std::vector<Eigen::Vector3d>& estimate,
                                const std::vector<Eigen::Vector3d>& ground_truth, AlignmentMode mode,
                                std::size_t first_n) {
  if (estimate.size() != ground_truth.size())
    throw std::invalid_argument("align_positions: " + std::to_string(estimate.size()) + " estimated and " +
                                std::to_string(ground_truth.size()) + " ground-truth positions");
  AlignmentResult result;
  result.mode = mode;
  const std::size_t n = first_n == 0 ? estimate.size() : std::min(first_n, estimate.size());
  result.pairs_used = n;
  const std::vector<Eigen::Vector3d> source(estimate.begin(), estimate.begin() + static_cast<std::ptrdiff_t>(n));
  const std::vector<Eigen::Vector3d> target(ground_truth.begin(), ground_truth.begin() + static_cast<std::ptrdiff_t>(n));

  if (mode == AlignmentMode::None) {
    if (!alignment_degeneracy(source) && !alignment_degeneracy(target))
      result.sim3_scale = umeyama_alignment(source, target, true).scale;
    return result;
  }
  const Sim3Transform sim3 = umeyama_alignment(source, target, true);
  result.sim3_scale = sim3.scale;
  result.transform = mode == AlignmentMode::Sim3 ? sim3 : umeyama_alignment(source, target, false);
  return result;
}

}  // namespace nirslam
