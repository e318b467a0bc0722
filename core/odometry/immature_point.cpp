#include "nirslam/odometry/immature_point.hpp"

#include <algorithm>
#include <cmath>

namespace nirslam::odometry {

ImmaturePoint::ImmaturePoint(const Eigen::Vector2i& pixel, const PyramidLevel& host) : pixel_(pixel.cast<double>()) {
  for (int i = 0; i < kPatternSize; ++i) {
    const auto& o = kPattern[static_cast<std::size_t>(i)];
    const Eigen::Vector3f& d = host.at(pixel.x() + o[0], pixel.y() + o[1]);
    host_intensity_[static_cast<std::size_t>(i)] = d[0];
    const Eigen::Vector2d g = d.tail<2>().cast<double>();
    host_structure_ += g * g.transpose();
  }
}

namespace {

// Inverse depth that puts the host ray at target pixel `pixel`: from q = R x + rho t with
// pi(q) = pixel, using the image axis along which the epipolar line moves most.
double inverse_depth_at(const LevelCamera& camera, const Eigen::Vector3d& Rx, const Eigen::Vector3d& t,
                        const Eigen::Vector2d& pixel, const Eigen::Vector2d& direction) {
  if (std::abs(direction.x()) > std::abs(direction.y())) {
    const double u = (pixel.x() - camera.cx) / camera.fx;
    return (Rx.x() - u * Rx.z()) / (u * t.z() - t.x());
  }
  const double v = (pixel.y() - camera.cy) / camera.fy;
  return (Rx.y() - v * Rx.z()) / (v * t.z() - t.y());
}

}  // namespace

TraceStatus ImmaturePoint::trace(const LevelCamera& camera, const PyramidLevel& target, const SE3& T_target_host,
                                 const AffineTransfer& affine, const TraceOptions& options, const LampGeometry& lamp) {
  const Eigen::Vector3d ray = camera.unproject(pixel_);
  const Eigen::Matrix3d R = T_target_host.rotation_matrix();
  const Eigen::Vector3d Rx = R * ray;
  const Eigen::Vector3d t = T_target_host.translation();
  const Eigen::Vector3d q_min = Rx + inverse_depth_min_ * t;
  if (q_min.z() <= 1e-6) return last_status_ = TraceStatus::OutOfBounds;
  const Eigen::Vector2d p_min = camera.project(q_min);
  if (!camera.inside(p_min.x(), p_min.y(), 4.0)) return last_status_ = TraceStatus::OutOfBounds;

  Eigen::Vector2d p_max;
  if (bounded()) {
    const Eigen::Vector3d q_max = Rx + inverse_depth_max_ * t;
    if (q_max.z() <= 1e-6) return last_status_ = TraceStatus::OutOfBounds;
    p_max = camera.project(q_max);
  } else {
    // Unbounded: walk max_search_px along the direction the line takes from p_min.
    const Eigen::Vector3d q_step = Rx + (inverse_depth_min_ + 0.01) * t;
    if (q_step.z() <= 1e-6) return last_status_ = TraceStatus::OutOfBounds;
    const Eigen::Vector2d d = camera.project(q_step) - p_min;
    if (d.norm() < 1e-9) return last_status_ = TraceStatus::BadCondition;
    p_max = p_min + d.normalized() * options.max_search_px;
  }
  Eigen::Vector2d direction = p_max - p_min;
  const double length = direction.norm();
  if (length < 1e-9) return last_status_ = TraceStatus::Skipped;
  direction /= length;
  if (bounded() && length < options.min_segment_px) {
    last_interval_px_ = length;
    return last_status_ = TraceStatus::Skipped;
  }

  // How well the pattern's gradients pin the match down along the line: (a + b) / a, a the
  // gradient energy along it, b across it.
  const double along = direction.dot(host_structure_ * direction);
  const Eigen::Vector2d across(-direction.y(), direction.x());
  const double perpendicular = across.dot(host_structure_ * across);
  const double error_px = 0.2 + 0.2 * (along + perpendicular) / std::max(along, 1e-9);
  if (error_px * 1.5 > length && bounded()) {
    last_interval_px_ = length;
    return last_status_ = TraceStatus::BadCondition;
  }

  // The host's brightness carried to the target at candidate `p`: the affine transfer, times
  // the lamp's factor for the inverse depth that puts the point there.
  auto transfer_scale = [&](const Eigen::Vector2d& p) {
    if (!lamp.enabled) return affine.scale;
    double rho = inverse_depth_at(camera, Rx, t, p, direction);
    if (!std::isfinite(rho)) rho = 0.0;
    return affine.scale * lamp_factor_value(ray, std::max(rho, 0.0), R, t, lamp);
  };
  auto pattern_energy = [&](const Eigen::Vector2d& p) {
    const double scale = transfer_scale(p);
    double e = 0.0;
    for (int i = 0; i < kPatternSize; ++i) {
      const auto& o = kPattern[static_cast<std::size_t>(i)];
      const double u = p.x() + o[0];
      const double v = p.y() + o[1];
      const double I = target.interpolate_intensity(static_cast<float>(u), static_cast<float>(v));
      const double r = I - scale * (host_intensity_[static_cast<std::size_t>(i)] - affine.b_host) - affine.b_target;
      const double hw = huber_weight(r, options.huber_threshold);
      e += hw * r * r * (2.0 - hw);
    }
    return e;
  };

  const int steps = std::max(1, static_cast<int>(std::ceil(std::min(length, options.max_search_px))));
  double best = 1e30;
  int best_step = -1;
  std::array<double, 128> energies{};
  const int n = std::min(steps + 1, static_cast<int>(energies.size()));
  for (int s = 0; s < n; ++s) {
    const Eigen::Vector2d p = p_min + static_cast<double>(s) * direction;
    if (!camera.inside(p.x(), p.y(), 4.0)) {
      energies[static_cast<std::size_t>(s)] = 1e30;
      continue;
    }
    const double e = pattern_energy(p);
    energies[static_cast<std::size_t>(s)] = e;
    if (e < best) {
      best = e;
      best_step = s;
    }
  }
  if (best_step < 0) return last_status_ = TraceStatus::OutOfBounds;
  double second = 1e30;
  for (int s = 0; s < n; ++s)
    if (std::abs(s - best_step) > 2) second = std::min(second, energies[static_cast<std::size_t>(s)]);
  quality_ = second / std::max(best, 1e-6);

  // Gauss-Newton along the line, sub-pixel.
  double offset = static_cast<double>(best_step);
  for (int it = 0; it < 3; ++it) {
    double H = 0.0;
    double g = 0.0;
    double e = 0.0;
    const Eigen::Vector2d p = p_min + offset * direction;
    const double scale = transfer_scale(p);  // held over the step, as the window holds g without derivatives
    for (int i = 0; i < kPatternSize; ++i) {
      const auto& o = kPattern[static_cast<std::size_t>(i)];
      const double u = p.x() + o[0];
      const double v = p.y() + o[1];
      if (!camera.inside(u, v, 1.0)) return last_status_ = TraceStatus::OutOfBounds;
      const Eigen::Vector3f s = target.interpolate(static_cast<float>(u), static_cast<float>(v));
      const double r = s[0] - scale * (host_intensity_[static_cast<std::size_t>(i)] - affine.b_host) - affine.b_target;
      const double hw = huber_weight(r, options.huber_threshold);
      const double J = s.tail<2>().cast<double>().dot(direction);
      H += hw * J * J;
      g += hw * J * r;
      e += hw * r * r * (2.0 - hw);
    }
    if (it == 0) best = e;
    if (H <= 1e-9) break;
    const double step = std::clamp(-g / H, -0.5, 0.5);
    offset += step;
    if (std::abs(step) < 1e-3) break;
  }
  best = pattern_energy(p_min + offset * direction);

  if (best > options.outlier_energy * kPatternSize) {
    ++outliers_;
    return last_status_ = TraceStatus::Outlier;
  }

  const Eigen::Vector2d p_lo = p_min + (offset - error_px) * direction;
  const Eigen::Vector2d p_hi = p_min + (offset + error_px) * direction;
  double rho_a = inverse_depth_at(camera, Rx, t, p_lo, direction);
  double rho_b = inverse_depth_at(camera, Rx, t, p_hi, direction);
  if (rho_a > rho_b) std::swap(rho_a, rho_b);
  if (!std::isfinite(rho_a) || !std::isfinite(rho_b) || rho_b < 0.0) {
    ++outliers_;
    return last_status_ = TraceStatus::Outlier;
  }
  inverse_depth_min_ = std::max(0.0, rho_a);
  inverse_depth_max_ = rho_b;
  last_interval_px_ = 2.0 * error_px;
  return last_status_ = TraceStatus::Good;
}

}  // namespace nirslam::odometry
