#include "nirslam/illumination/saturation_curve.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <Eigen/Dense>

namespace nirslam {

const char* to_string(CurveModel model) {
  switch (model) {
    case CurveModel::Exponential: return "exponential";
    case CurveModel::StretchedExponential: return "stretched exponential";
  }
  return "unknown";
}

double SaturationCurve::operator()(double power_w) const {
  const double u = std::pow(std::max(power_w, 0.0) / p_s_w, beta);
  return h_max_bits - (h_max_bits - h0_bits) * std::exp(-u);
}

Eigen::Vector4d SaturationCurve::jacobian(double power_w) const {
  const double ratio = std::max(power_w, 0.0) / p_s_w;
  const double u = std::pow(ratio, beta);
  const double e = std::exp(-u);
  const double rise = h_max_bits - h0_bits;
  // H = h_max - rise e^-u with u = (P / p_s)^beta:
  //   du/d(ln p_s) = -beta u,   du/d(beta) = u ln(P / p_s)   (0 at P = 0).
  const double du_dbeta = ratio > 0.0 ? u * std::log(ratio) : 0.0;
  return {e, 1.0 - e, -rise * e * beta * u, rise * e * du_dbeta};
}

double SaturationCurve::power_for_share(double share) const {
  const double rise = h_max_bits - h0_bits;
  const double gap = (1.0 - share) * h_max_bits;  // how far below the plateau is close enough
  if (h_max_bits <= 0.0 || rise <= gap) return 0.0;
  return p_s_w * std::pow(std::log(rise / gap), 1.0 / beta);
}

Eigen::Vector4d SaturationCurve::power_for_share_jacobian(double share) const {
  const double power = power_for_share(share);
  if (power <= 0.0) return Eigen::Vector4d::Zero();
  // P = p_s L^(1/beta), L = ln(h_max - h0) - ln(1 - share) - ln h_max: dP/dL = P / (beta L).
  const double rise = h_max_bits - h0_bits;
  const double log_ratio = std::log(rise / ((1.0 - share) * h_max_bits));
  const double dp_dl = power / (beta * log_ratio);
  return {-dp_dl / rise, dp_dl * (1.0 / rise - 1.0 / h_max_bits), power,
          -power * std::log(log_ratio) / (beta * beta)};
}

namespace {

using Vector4 = Eigen::Vector4d;
using Matrix4 = Eigen::Matrix4d;

struct Problem {
  std::vector<CurveSample> samples;
  double min_log_scale = 0.0;
  double max_log_scale = 0.0;
  double max_plateau = 8.0;
  double min_beta = 1.0;
  double max_beta = 1.0;
  bool beta_free = false;
};

SaturationCurve curve_of(const Vector4& x) { return {x[0], x[1], std::exp(x[2]), x[3]}; }

double cost_of(const Problem& problem, const Vector4& x) {
  const SaturationCurve curve = curve_of(x);
  double cost = 0.0;
  for (const CurveSample& s : problem.samples) {
    const double r = curve(s.power_w) - s.entropy_bits;
    cost += s.weight * r * r;
  }
  return cost;
}

// Normal equations J^T W J and J^T W r at x; a fixed beta gets an identity row and no gradient.
void normal_equations(const Problem& problem, const Vector4& x, Matrix4& jtj, Vector4& jtr) {
  const SaturationCurve curve = curve_of(x);
  jtj.setZero();
  jtr.setZero();
  for (const CurveSample& s : problem.samples) {
    Vector4 j = curve.jacobian(s.power_w);
    if (!problem.beta_free) j[3] = 0.0;
    const double r = curve(s.power_w) - s.entropy_bits;
    jtj.noalias() += s.weight * j * j.transpose();
    jtr.noalias() += s.weight * r * j;
  }
}

// Keeps the parameters inside their box.
Vector4 project(const Problem& problem, Vector4 x) {
  x[1] = std::min(x[1], problem.max_plateau);
  x[2] = std::clamp(x[2], problem.min_log_scale, problem.max_log_scale);
  x[3] = problem.beta_free ? std::clamp(x[3], problem.min_beta, problem.max_beta) : 1.0;
  return x;
}

// For fixed P_s and beta the model H = h_max + (h0 - h_max) e, e = exp(-(P / P_s)^beta), is linear
// in (h_max, h0 - h_max): weighted linear least squares over a grid gives a start near the optimum.
Vector4 grid_start(const Problem& problem) {
  constexpr int kScaleSteps = 96;
  std::vector<double> betas{1.0};
  if (problem.beta_free) {
    betas.clear();
    for (double b = problem.min_beta; b <= problem.max_beta + 1e-9; b *= 1.15) betas.push_back(b);
    betas.push_back(1.0);
  }
  Vector4 best(0.0, 0.0, problem.min_log_scale, 1.0);
  double best_cost = std::numeric_limits<double>::infinity();
  for (const double beta : betas) {
    for (int k = 0; k <= kScaleSteps; ++k) {
      const double log_scale =
          problem.min_log_scale + (problem.max_log_scale - problem.min_log_scale) * k / static_cast<double>(kScaleSteps);
      const double scale = std::exp(log_scale);
      double sw = 0.0, swe = 0.0, swee = 0.0, swy = 0.0, swey = 0.0;
      for (const CurveSample& s : problem.samples) {
        const double e = std::exp(-std::pow(s.power_w / scale, beta));
        sw += s.weight;
        swe += s.weight * e;
        swee += s.weight * e * e;
        swy += s.weight * s.entropy_bits;
        swey += s.weight * e * s.entropy_bits;
      }
      const double det = sw * swee - swe * swe;
      if (!(std::abs(det) > 1e-12 * sw * swee)) continue;
      double h_max = (swee * swy - swe * swey) / det;
      double b = (sw * swey - swe * swy) / det;
      if (h_max > problem.max_plateau) {
        h_max = problem.max_plateau;
        b = (swey - h_max * swe) / swee;
      }
      const Vector4 x(h_max + b, h_max, log_scale, beta);
      const double cost = cost_of(problem, x);
      if (cost < best_cost) {
        best_cost = cost;
        best = x;
      }
    }
  }
  return best;
}

SaturationFit solve(const Problem& problem, const SaturationFitOptions& options) {
  Vector4 x = grid_start(problem);
  double cost = cost_of(problem, x);
  double lambda = 1e-3;
  SaturationFit fit;
  for (fit.iterations = 0; fit.iterations < options.max_iterations; ++fit.iterations) {
    Matrix4 jtj;
    Vector4 jtr;
    normal_equations(problem, x, jtj, jtr);
    if (jtr.lpNorm<Eigen::Infinity>() < 1e-14) {
      fit.converged = true;
      break;
    }
    if (!problem.beta_free) jtj(3, 3) = 1.0;
    bool improved = false;
    while (lambda < 1e12) {
      Matrix4 damped = jtj;
      for (int i = 0; i < 4; ++i) damped(i, i) += lambda * std::max(jtj(i, i), 1e-12);
      const Vector4 step = damped.ldlt().solve(-jtr);
      const Vector4 candidate = project(problem, x + step);
      const double candidate_cost = cost_of(problem, candidate);
      if (std::isfinite(candidate_cost) && candidate_cost < cost) {
        const double decrease = cost - candidate_cost;
        const double moved = (candidate - x).norm();
        x = candidate;
        cost = candidate_cost;
        lambda = std::max(lambda / 3.0, 1e-12);
        improved = true;
        if (decrease <= 1e-14 * (1.0 + cost) || moved <= 1e-12 * (1.0 + x.norm())) fit.converged = true;
        break;
      }
      lambda *= 4.0;
    }
    // No step lowers the cost: x is a minimum (within the box) to machine precision.
    if (!improved) fit.converged = true;
    if (fit.converged) break;
  }

  fit.model = problem.beta_free ? CurveModel::StretchedExponential : CurveModel::Exponential;
  fit.curve = curve_of(x);
  fit.samples = static_cast<int>(problem.samples.size());
  fit.parameters = problem.beta_free ? 4 : 3;
  fit.cost = cost;
  double weight_sum = 0.0;
  for (const CurveSample& s : problem.samples) weight_sum += s.weight;
  fit.rms_residual_bits = std::sqrt(cost / weight_sum);
  const int n = fit.samples;
  const int k = fit.parameters;
  // Corrected AIC of a least-squares fit (Hurvich & Tsai): n ln(RSS / n) + 2k + 2k(k + 1)/(n - k - 1),
  // with the weights normalised to the number of samples; infinite without enough samples.
  const double normalised = std::max(cost / weight_sum, 1e-300);
  fit.aicc = n - k - 1 > 0 ? n * std::log(normalised) + 2.0 * k + 2.0 * k * (k + 1.0) / (n - k - 1)
                           : std::numeric_limits<double>::infinity();
  fit.plateau_at_bound = x[1] >= problem.max_plateau - 1e-9;
  fit.scale_at_bound = x[2] <= problem.min_log_scale + 1e-6 || x[2] >= problem.max_log_scale - 1e-6;
  if (n > k) {
    Matrix4 jtj;
    Vector4 jtr;
    normal_equations(problem, x, jtj, jtr);
    const Eigen::MatrixXd free = jtj.topLeftCorner(k, k);
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(free);
    if (lu.rank() == k) {
      Matrix4 covariance = Matrix4::Zero();
      covariance.topLeftCorner(k, k) = lu.inverse() * (cost / (n - k));
      fit.covariance = covariance;
    }
  }
  return fit;
}

Problem make_problem(std::span<const CurveSample> samples, const SaturationFitOptions& options, int& distinct_powers) {
  Problem problem;
  problem.max_plateau = options.max_plateau_bits;
  std::vector<double> powers;
  for (const CurveSample& s : samples) {
    if (!std::isfinite(s.power_w) || s.power_w < 0.0 || !std::isfinite(s.entropy_bits) || !std::isfinite(s.weight) ||
        s.weight < 0.0)
      throw std::invalid_argument("saturation fit: powers must be finite and >= 0, entropies finite, weights >= 0");
    if (s.weight == 0.0) continue;
    problem.samples.push_back(s);
    powers.push_back(s.power_w);
  }
  std::sort(powers.begin(), powers.end());
  distinct_powers = static_cast<int>(
      std::unique(powers.begin(), powers.end(), [](double a, double b) { return b - a < 1e-9; }) - powers.begin());
  if (!powers.empty() && powers.back() > 0.0) {
    problem.min_log_scale = std::log(options.min_scale * powers.back());
    problem.max_log_scale = std::log(options.max_scale * powers.back());
  }
  problem.min_beta = options.min_beta;
  problem.max_beta = options.max_beta;
  return problem;
}

}  // namespace

std::optional<SaturationFit> fit_saturation_curve(std::span<const CurveSample> samples, CurveModel model,
                                                  const SaturationFitOptions& options) {
  int distinct = 0;
  Problem problem = make_problem(samples, options, distinct);
  problem.beta_free = model == CurveModel::StretchedExponential;
  if (distinct < (problem.beta_free ? 4 : 3)) return std::nullopt;
  return solve(problem, options);
}

std::optional<SaturationFit> fit_saturation_curve(std::span<const CurveSample> samples,
                                                  const SaturationFitOptions& options) {
  int distinct = 0;
  make_problem(samples, options, distinct);
  std::optional<SaturationFit> exponential = fit_saturation_curve(samples, CurveModel::Exponential, options);
  if (!exponential || !options.allow_stretched || distinct < options.min_powers_for_stretched) return exponential;
  std::optional<SaturationFit> stretched = fit_saturation_curve(samples, CurveModel::StretchedExponential, options);
  if (!stretched || !(stretched->aicc < exponential->aicc - options.aicc_margin)) return exponential;
  stretched->exponential_rms_bits = exponential->rms_residual_bits;
  return stretched;
}

}  // namespace nirslam
