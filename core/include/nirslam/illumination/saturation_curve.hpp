#pragma once

// Image entropy as a function of illuminator power: it rises as the light lifts the scene out of
// the dark and saturates once every surface in view is well exposed (the paper's Table 1). The
// model is a (stretched) first-order step response,
//
//   H(P) = H_max - (H_max - H_0) exp(-(P / P_s)^beta)
//
// H_0: entropy with the illuminator off (ambient light only), H_max: the plateau, P_s: the power
// scale, beta: the shape. With beta = 1 it is the plain exponential approach (63 % of the rise done
// at P_s, 95 % at 3 P_s): the default model, three parameters an operator can read and a
// closed-form inverse. Deep scenes, whose far surfaces keep brightening after the near ones are
// well exposed, rise fast and then creep on: a stretched exponential (beta < 1) follows that tail,
// and is used when it fits clearly better (corrected Akaike criterion, see fit_saturation_curve).
//
// The fit is weighted least squares over x = (H_0, H_max, ln P_s, beta) (ln keeps P_s positive and
// scales the problem): a variable-projection grid for the start (for fixed P_s and beta the model
// is linear in H_0 and H_max), then Levenberg-Marquardt with the analytic Jacobian. H_max is held at
// or below 8 bits, the entropy of 256 equally filled bins.

#include <optional>
#include <span>

#include <Eigen/Core>

namespace nirslam {

struct SaturationCurve {
  double h0_bits = 0.0;
  double h_max_bits = 0.0;
  double p_s_w = 1.0;
  double beta = 1.0;

  double operator()(double power_w) const;

  // dH/d(h0, h_max, ln p_s, beta) at `power_w`.
  Eigen::Vector4d jacobian(double power_w) const;

  // The lowest power at which H(P) >= share * h_max, for share in (0, 1):
  //   P = p_s (ln((h_max - h0) / ((1 - share) h_max)))^(1 / beta),
  // 0 when the curve starts there already (h0 >= share * h_max, or h_max <= 0).
  double power_for_share(double share) const;
  // d power_for_share / d(h0, h_max, ln p_s, beta); zero where power_for_share is 0.
  Eigen::Vector4d power_for_share_jacobian(double share) const;
};

struct CurveSample {
  double power_w = 0.0;
  double entropy_bits = 0.0;
  double weight = 1.0;  // relative weight of the residual's square (e.g. frames averaged)
};

enum class CurveModel {
  Exponential,         // beta = 1: three parameters
  StretchedExponential // beta free: four parameters
};
const char* to_string(CurveModel model);

struct SaturationFitOptions {
  int max_iterations = 200;
  double max_plateau_bits = 8.0;
  // P_s is searched within [min_scale, max_scale] times the highest sample power.
  double min_scale = 0.01;
  double max_scale = 20.0;
  // The stretched model is tried with at least this many distinct powers (it needs residual
  // degrees of freedom to be judged), beta within [min_beta, max_beta].
  int min_powers_for_stretched = 6;
  double min_beta = 0.25;
  double max_beta = 3.0;
  // How much lower the stretched model's corrected AIC must be to be chosen.
  double aicc_margin = 2.0;
  bool allow_stretched = true;
};

struct SaturationFit {
  CurveModel model = CurveModel::Exponential;
  SaturationCurve curve{};
  int samples = 0;
  int parameters = 3;
  double cost = 0.0;               // sum of weighted squared residuals, bits^2
  double rms_residual_bits = 0.0;  // sqrt(cost / sum of weights)
  double aicc = 0.0;               // corrected Akaike criterion of the fit (lower is better)
  // The exponential's RMS residual when the stretched model was chosen over it (for the reasons).
  std::optional<double> exponential_rms_bits{};
  // Covariance of (h0, h_max, ln p_s, beta): s^2 (J^T W J)^-1 over the free parameters, with
  // s^2 = cost / (n - k), the usual estimate from the residual; beta's row and column are zero for
  // the exponential. Empty without a degree of freedom left, or when J^T W J is singular.
  std::optional<Eigen::Matrix4d> covariance{};
  bool converged = false;
  int iterations = 0;
  bool plateau_at_bound = false;   // H_max was held at max_plateau_bits
  bool scale_at_bound = false;     // P_s was held at an end of its search range: no saturation seen
};

// Fits the exponential and, with enough distinct powers, the stretched model, and returns the one
// with the lower corrected AIC (the stretched one only when lower by aicc_margin). Samples at three
// or more distinct powers; std::nullopt otherwise. Negative or non-finite powers, entropies or
// weights throw std::invalid_argument.
std::optional<SaturationFit> fit_saturation_curve(std::span<const CurveSample> samples,
                                                  const SaturationFitOptions& options = {});

// One model only.
std::optional<SaturationFit> fit_saturation_curve(std::span<const CurveSample> samples, CurveModel model,
                                                  const SaturationFitOptions& options = {});

}  // namespace nirslam
