#include "nirslam/illumination/light_offset_estimator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "nirslam/common/huber.hpp"
#include "nirslam/common/median.hpp"

namespace nirslam {

LightOffsetEstimator::LightOffsetEstimator(LightOffsetEstimatorOptions options) : options_(options) {}

void LightOffsetEstimator::clear() {
  observations_.clear();
  point_start_.assign(1, 0);
  rejected_points_ = 0;
}

void LightOffsetEstimator::add_point(std::span<const LampObservation> observations) {
  int usable = 0;
  for (const LampObservation& o : observations)
    if (o.p_cam.allFinite() && o.p_cam.z() > 0.0 && std::isfinite(o.log_irradiance) &&
        (!o.normal_cam || o.normal_cam->allFinite()))
      ++usable;
  if (usable < options_.min_observations_per_point) {
    ++rejected_points_;
    return;
  }
  for (const LampObservation& o : observations)
    if (o.p_cam.allFinite() && o.p_cam.z() > 0.0 && std::isfinite(o.log_irradiance) &&
        (!o.normal_cam || o.normal_cam->allFinite()))
      observations_.push_back(o);
  point_start_.push_back(static_cast<int>(observations_.size()));
}

double LightOffsetEstimator::log_falloff(const LampObservation& o, const Eigen::Vector3d& light_cam,
                                         Eigen::Vector3d* d_light, double beam_exponent) {
  const Eigen::Vector3d to_light = light_cam - o.p_cam;
  const double d2 = to_light.squaredNorm();
  double f = -std::log(d2);
  Eigen::Vector3d g = -2.0 * to_light / d2;
  if (o.normal_cam) {
    // cos(theta) = n . v / |v|: one more 1/d and the projection on the normal.
    const double n_dot_v = o.normal_cam->dot(to_light);
    if (n_dot_v <= 0.0) {  // the lamp behind the surface: no light, no information
      if (d_light) d_light->setZero();
      return std::numeric_limits<double>::quiet_NaN();
    }
    f += std::log(n_dot_v) - 0.5 * std::log(d2);
    g += *o.normal_cam / n_dot_v - to_light / d2;
  }
  if (beam_exponent > 0.0) {
    // cos(alpha) = (p - L)_z / |p - L| off the beam's axis (the camera's z).
    const double along_axis = -to_light.z();
    if (along_axis <= 0.0) {
      if (d_light) d_light->setZero();
      return std::numeric_limits<double>::quiet_NaN();
    }
    f += beam_exponent * (std::log(along_axis) - 0.5 * std::log(d2));
    g += beam_exponent * (Eigen::Vector3d::UnitZ() / to_light.z() - to_light / d2);
  }
  if (d_light) *d_light = g;
  return f;
}

std::optional<double> LightOffsetEstimator::mean_albedo(int point, const Eigen::Vector3d& light) const {
  double sum = 0.0;
  int count = 0;
  for (int k = point_start_[point]; k < point_start_[point + 1]; ++k) {
    const double f = log_falloff(observations_[k], light, nullptr, options_.beam_exponent);
    if (!std::isfinite(f)) continue;
    sum += observations_[k].log_irradiance - f;
    ++count;
  }
  if (count < options_.min_observations_per_point) return std::nullopt;
  return sum / count;
}

// Cost at `light` with every point's albedo at its (weighted) optimum; the rms of the residuals.
double LightOffsetEstimator::robust_cost(const Eigen::Vector3d& light, double* rms, double* robust_sigma) const {
  double cost = 0.0, sum_r2 = 0.0;
  int n = 0;
  std::vector<double> absolute;
  if (robust_sigma) absolute.reserve(observations_.size());
  for (int p = 0; p + 1 < static_cast<int>(point_start_.size()); ++p) {
    const std::optional<double> mean = mean_albedo(p, light);
    if (!mean) continue;
    // A median-free albedo: the mean, then the Huber-weighted mean once (outliers barely move it).
    double albedo = *mean;
    double weighted = 0.0, weights = 0.0;
    for (int k = point_start_[p]; k < point_start_[p + 1]; ++k) {
      const double f = log_falloff(observations_[k], light, nullptr, options_.beam_exponent);
      if (!std::isfinite(f)) continue;
      const double x = observations_[k].log_irradiance - f;
      const double w = huber_weight(x - albedo, options_.huber_log);
      weighted += w * x;
      weights += w;
    }
    albedo = weighted / weights;
    for (int k = point_start_[p]; k < point_start_[p + 1]; ++k) {
      const double f = log_falloff(observations_[k], light, nullptr, options_.beam_exponent);
      if (!std::isfinite(f)) continue;
      const double r = observations_[k].log_irradiance - albedo - f;
      cost += huber_loss(r, options_.huber_log);
      sum_r2 += r * r;
      ++n;
      if (robust_sigma) absolute.push_back(std::abs(r));
    }
  }
  if (rms) *rms = n > 0 ? std::sqrt(sum_r2 / n) : 0.0;
  if (robust_sigma) {
    // 1.4826 x the median absolute residual: the noise's sigma, whatever a few glints do.
    *robust_sigma = 0.0;
    if (!absolute.empty()) {
      const auto middle = absolute.begin() + static_cast<std::ptrdiff_t>(absolute.size() / 2);
      std::nth_element(absolute.begin(), middle, absolute.end());
      *robust_sigma = 1.4826 * *middle;
    }
  }
  return cost;
}

LightOffsetEstimate LightOffsetEstimator::estimate(const Eigen::Vector3d& start) const {
  LightOffsetEstimate out;
  out.offset_cam = start;
  out.points = points();
  out.observations = static_cast<int>(observations_.size());
  if (out.points < options_.min_points) {
    out.reason = fmt::format("{} points seen from several poses, {} needed", out.points, options_.min_points);
    return out;
  }
  std::vector<double> distances;
  distances.reserve(observations_.size());
  for (const LampObservation& o : observations_) distances.push_back(o.p_cam.norm());
  out.median_distance = median_in_place(distances);
  // In the residuals' units: the data terms are squared log errors of about the sensor's noise.
  const double prior_information = std::pow(options_.min_residual_sigma / (options_.prior_sigma_fraction * out.median_distance), 2);

  Eigen::Vector3d light = start;
  double cost = robust_cost(light, &out.rms_log_before) + 0.5 * prior_information * light.squaredNorm();
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d H_data = Eigen::Matrix3d::Zero();
  double sum_wr2 = 0.0;
  int used = 0;
  for (int iteration = 0; iteration < options_.max_iterations; ++iteration) {
    // Normal equations in L with each albedo eliminated: per point, the Huber-weighted
    // sums give H_LL - H_La H_aa^-1 H_aL and, with the albedo at its optimum, b_L alone.
    H.setZero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    sum_wr2 = 0.0;
    used = 0;
    for (int p = 0; p + 1 < static_cast<int>(point_start_.size()); ++p) {
      const std::optional<double> albedo_mean = mean_albedo(p, light);
      if (!albedo_mean) continue;
      const double albedo = *albedo_mean;
      double h_aa = 0.0;
      Eigen::Vector3d h_al = Eigen::Vector3d::Zero();
      Eigen::Matrix3d h_ll = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b_l = Eigen::Vector3d::Zero();
      double b_a = 0.0;
      for (int k = point_start_[p]; k < point_start_[p + 1]; ++k) {
        Eigen::Vector3d g;
        const double f = log_falloff(observations_[k], light, &g, options_.beam_exponent);
        if (!std::isfinite(f)) continue;
        const double r = observations_[k].log_irradiance - albedo - f;  // dr/da = -1, dr/dL = -g
        const double w = huber_weight(r, options_.huber_log);
        h_aa += w;
        h_al += w * g;
        h_ll += w * g * g.transpose();
        b_l -= w * r * g;
        b_a -= w * r;
        sum_wr2 += w * r * r;
        ++used;
      }
      H += h_ll - h_al * h_al.transpose() / h_aa;
      b += b_l - h_al * (b_a / h_aa);
    }
    H_data = H;
    H += prior_information * Eigen::Matrix3d::Identity();
    b += prior_information * light;
    const Eigen::Vector3d step = -H.ldlt().solve(b);
    if (!step.allFinite()) break;
    // Halve the step until the robust cost goes down (Gauss-Newton overshoots far from L).
    bool accepted = false;
    for (double scale = 1.0; scale > 1e-3; scale *= 0.5) {
      const Eigen::Vector3d trial = light + scale * step;
      const double trial_cost = robust_cost(trial, nullptr) + 0.5 * prior_information * trial.squaredNorm();
      if (trial_cost < cost) {
        light = trial;
        cost = trial_cost;
        accepted = true;
        break;
      }
    }
    out.iterations = iteration + 1;
    if (!accepted || step.norm() < 1e-6 * out.median_distance) break;
  }
  robust_cost(light, &out.rms_log_after, &out.robust_sigma_log);
  out.offset_cam = light;
  // Covariance from the data alone (the prior would make any direction look determined), with
  // the weighted residual variance (3 parameters plus one albedo per point), floored at the
  // sensor's own noise so exact data do not claim infinite precision.
  const int dof = std::max(1, used - out.points - 3);
  const double sigma2 = std::max(sum_wr2 / dof, options_.min_residual_sigma * options_.min_residual_sigma);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(H_data);
  const double tiny = 1e-12 * std::max(1.0, eigen.eigenvalues().cwiseAbs().maxCoeff());
  Eigen::Vector3d inverse_eigenvalues;
  for (int i = 0; i < 3; ++i)
    inverse_eigenvalues(i) = eigen.eigenvalues()(i) > tiny ? 1.0 / eigen.eigenvalues()(i) : 1e30;
  out.covariance = sigma2 * eigen.eigenvectors() * inverse_eigenvalues.asDiagonal() * eigen.eigenvectors().transpose();
  if (!out.covariance.allFinite() || !light.allFinite()) {
    out.offset_cam = start;
    out.reason = "the solve did not give a finite offset";
    return out;
  }
  const Eigen::Vector3d sigma = out.sigma();
  const double limit = options_.max_sigma_fraction * out.median_distance;
  if (sigma.maxCoeff() > limit) {
    static constexpr const char* kAxes = "xyz";
    Eigen::Index axis = 0;
    sigma.maxCoeff(&axis);
    out.reason = fmt::format("not determined along {}: sigma {:.3g} > {:.3g} (the poses do not see the lamp's "
                             "falloff change enough)", kAxes[axis], sigma(axis), limit);
    return out;
  }
  if (out.robust_sigma_log > options_.max_sigma_log) {
    out.reason = fmt::format("the lamp model does not fit the brightness (robust sigma {:.3f} in log, above {:.3f}): "
                             "the halo factor, the response or the depths are off", out.robust_sigma_log, options_.max_sigma_log);
    return out;
  }
  if (light.norm() > options_.max_offset_fraction * out.median_distance) {
    out.reason = fmt::format("offset {:.3g} is implausibly far from the camera (median point distance {:.3g})",
                             light.norm(), out.median_distance);
    return out;
  }
  out.determined = true;
  return out;
}

}  // namespace nirslam
