#include "nirslam/photometric/exposure_sweep_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string_view>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/common/huber.hpp"
#include "nirslam/common/median.hpp"
#include "nirslam/common/text_fields.hpp"

namespace nirslam {

std::string to_string(SweepAmbiguityResolution resolution) {
  switch (resolution) {
    case SweepAmbiguityResolution::KnownExposureTimes:
      return "known exposure times (log e_j = log(t_j / t_ref); scale pinned by f(1) = 1)";
    case SweepAmbiguityResolution::ReferenceImageNormalisation:
      return "reference image normalisation (e_ref = 1; gamma pinned only by the response basis and the prior)";
    case SweepAmbiguityResolution::FixedPriorResponse:
      return "fixed prior response (exposures estimated with e_ref = 1 and f held at the prior)";
    case SweepAmbiguityResolution::IlluminatorPowerSweep:
      return "illuminator power sweep (the lamp's irradiance proportional to power x exposure x gain)";
  }
  return "unknown";
}

namespace {

constexpr int kMonotonicGrid = 256;
constexpr double kMinSlope = 0.01;  // df/du lower bound enforced by the penalty

struct Observation {
  int image = 0;
  double grey = 0.0;  // normalised to [0, 1]
};

ExposureSweepResult degenerate(ExposureSweepResult result, const ExposureSweepOptions& options, std::string reason) {
  result.ok = false;
  result.reason = std::move(reason);
  result.response = options.prior;
  result.residual_rms_grey = 0.0;
  result.monotonic = options.prior.is_monotonic();
  return result;
}

}  // namespace

double sweep_prediction(const Eigen::Vector4d& c, double log_irradiance, Eigen::Matrix<double, 5, 1>* jacobian) {
  const double u = std::exp(0.5 * log_irradiance);
  Eigen::Vector4d h, dh;
  response_basis_in_sqrt_irradiance(u, h, dh);
  const double f = u + c.dot(h);
  if (jacobian != nullptr) {
    jacobian->head<4>() = h;
    (*jacobian)[4] = (1.0 + c.dot(dh)) * 0.5 * u;  // df/du * du/dlogX
  }
  return f;
}

namespace {

// What the fit knows of each image's exposure. `lamp`: the known exposures (times, or power x
// time for a power sweep), nothing to estimate them. `ambient`: each image's exposure time x gain
// when the scene also holds light that does not scale with the lamp (then `lamp` is known and may
// be 0 for a lamp-off image).
struct SweepExposures {
  const std::optional<std::vector<double>>& lamp;
  const std::optional<std::vector<double>>& ambient;
};

constexpr double kMaxAmbient = 1e4;  // b_i in units of the lamp's irradiance at the reference image

ExposureSweepResult fit_sweep(const std::vector<cv::Mat>& images, const SweepExposures& given,
                              const ExposureSweepOptions& options) {
  ExposureSweepResult result;
  const int n = static_cast<int>(images.size());
  const bool known = given.lamp.has_value();
  const bool ambient = given.ambient.has_value();
  result.resolution = known                   ? SweepAmbiguityResolution::KnownExposureTimes
                      : options.fix_response ? SweepAmbiguityResolution::FixedPriorResponse
                                             : SweepAmbiguityResolution::ReferenceImageNormalisation;
  result.ambient_modelled = ambient;
  result.images.resize(static_cast<std::size_t>(n));
  result.response = options.prior;
  const auto lamp_exposure = [&](int j) { return (*given.lamp)[static_cast<std::size_t>(j)]; };
  const auto ambient_exposure = [&](int j) { return (*given.ambient)[static_cast<std::size_t>(j)]; };

  // ---- input checks
  if (known) {
    if (static_cast<int>(given.lamp->size()) != n)
      return degenerate(result, options,
                        "got " + std::to_string(given.lamp->size()) + " exposure times for " + std::to_string(n) +
                            " images");
    if (ambient && static_cast<int>(given.ambient->size()) != n)
      return degenerate(result, options,
                        "got " + std::to_string(given.ambient->size()) + " ambient exposures for " + std::to_string(n) +
                            " images");
    for (int j = 0; j < n; ++j) {
      const double t = lamp_exposure(j);
      if (ambient) {
        // A lamp-off image (0) sees the ambient light alone: it observes the ambient term directly.
        if (!std::isfinite(t) || t < 0.0)
          return degenerate(result, options, "lamp exposure of image " + std::to_string(j) + " is negative");
        if (!std::isfinite(ambient_exposure(j)) || ambient_exposure(j) <= 0.0)
          return degenerate(result, options, "exposure time of image " + std::to_string(j) + " is not positive");
      } else if (!std::isfinite(t) || t <= 0.0) {
        return degenerate(result, options, "exposure time of image " + std::to_string(j) + " is not positive");
      }
      result.images[static_cast<std::size_t>(j)].exposure = t;
    }
  } else if (ambient) {
    return degenerate(result, options, "the ambient term needs the known exposures");
  }
  if (n < 2) return degenerate(result, options, "fewer than 2 images (" + std::to_string(n) + ")");
  for (int j = 0; j < n; ++j) {
    const cv::Mat& image = images[static_cast<std::size_t>(j)];
    if (image.empty() || image.type() != CV_8UC1)
      return degenerate(result, options, "image " + std::to_string(j) + " is empty or not 8-bit grey");
    if (image.size() != images[0].size())
      return degenerate(result, options, "image " + std::to_string(j) + " differs in size from image 0");
  }
  if (options.fix_response && !options.prior.is_monotonic())
    return degenerate(result, options, "fix_response needs a monotonic prior response");
  const int width = images[0].cols;
  const int height = images[0].rows;
  if (width < 8 || height < 8) return degenerate(result, options, "images smaller than 8x8");

  // ---- per image: 3x3 mean (the sample), 3x3 min and max (the clipping test), gradient score
  std::vector<cv::Mat> mean(static_cast<std::size_t>(n)), lo(static_cast<std::size_t>(n)), hi(static_cast<std::size_t>(n));
  cv::Mat score(height, width, CV_32FC1, cv::Scalar(0.0f));
  const cv::Mat kernel = cv::Mat::ones(3, 3, CV_8UC1);
  for (int j = 0; j < n; ++j) {
    const auto sj = static_cast<std::size_t>(j);
    images[sj].convertTo(mean[sj], CV_32FC1);
    cv::blur(mean[sj], mean[sj], cv::Size(3, 3));
    cv::erode(images[sj], lo[sj], kernel);
    cv::dilate(images[sj], hi[sj], kernel);
    cv::Mat gx, gy, magnitude;
    cv::Sobel(mean[sj], gx, CV_32F, 1, 0, 3);
    cv::Sobel(mean[sj], gy, CV_32F, 0, 1, 3);
    magnitude = cv::abs(gx) + cv::abs(gy);
    score = cv::max(score, magnitude);
  }
  const auto unclipped = [&](int j, int row, int col) {
    const auto sj = static_cast<std::size_t>(j);
    return lo[sj].at<unsigned char>(row, col) >= options.min_valid_grey &&
           hi[sj].at<unsigned char>(row, col) <= options.max_valid_grey;
  };
  // With the ambient term a point has two unknowns (lamp and ambient radiance).
  const int min_observations = ambient ? 3 : 2;

  // ---- candidate positions: a grid with ~4x the wanted points, unclipped in enough images,
  // the lowest gradient score (max over images) kept.
  const int wanted = std::max(1, options.max_points);
  const double stride_f = std::sqrt(static_cast<double>(width - 4) * (height - 4) / (4.0 * wanted));
  const int stride = std::max(1, static_cast<int>(stride_f));
  struct Candidate {
    int row, col;
    float score;
  };
  std::vector<Candidate> candidates;
  for (int row = 2; row < height - 2; row += stride)
    for (int col = 2; col < width - 2; col += stride) {
      int count = 0;
      for (int j = 0; j < n && count < min_observations; ++j) count += unclipped(j, row, col) ? 1 : 0;
      if (count >= min_observations) candidates.push_back({row, col, score.at<float>(row, col)});
    }
  if (static_cast<int>(candidates.size()) > wanted) {
    std::nth_element(candidates.begin(), candidates.begin() + wanted, candidates.end(),
                     [](const Candidate& a, const Candidate& b) { return a.score < b.score; });
    candidates.resize(static_cast<std::size_t>(wanted));
  }
  const int sampled = static_cast<int>(candidates.size());

  // ---- which images are usable
  std::vector<int> used_images;
  for (int j = 0; j < n; ++j) {
    auto& info = result.images[static_cast<std::size_t>(j)];
    for (const auto& cand : candidates) info.unclipped_samples += unclipped(j, cand.row, cand.col) ? 1 : 0;
    const int need = std::max(2, static_cast<int>(std::ceil(options.min_unclipped_fraction * std::max(sampled, 1))));
    if (sampled == 0 || info.unclipped_samples < need) {
      const double mean_grey = cv::mean(images[static_cast<std::size_t>(j)])[0];
      info.note = "only " + std::to_string(info.unclipped_samples) + " of " + std::to_string(sampled) +
                  " samples unclipped (" + (mean_grey < 128.0 ? "mostly black" : "mostly saturated") + ")";
    } else {
      info.used = true;
      used_images.push_back(j);
    }
  }
  const auto lamp_on = [&](int j) { return !known || lamp_exposure(j) > 0.0; };
  const auto lit = std::count_if(used_images.begin(), used_images.end(), lamp_on);
  if (lit < 2)
    return degenerate(result, options,
                      "fewer than 2 usable images (" + std::to_string(lit) + "): the others are black or saturated" +
                          (ambient ? " or lamp-off" : ""));
  const int reference = *std::find_if(used_images.begin(), used_images.end(), lamp_on);
  result.reference_image = reference;

  if (known) {
    double t_min = 1e300, t_max = 0.0;
    for (int j : used_images) {
      if (!lamp_on(j)) continue;
      t_min = std::min(t_min, lamp_exposure(j));
      t_max = std::max(t_max, lamp_exposure(j));
    }
    if (t_max / t_min < 1.02) return degenerate(result, options, "no exposure variation among the usable images");
  }

  // ---- observations, grouped by point (only points seen unclipped in enough used images)
  std::vector<Observation> observations;
  std::vector<int> point_begin{0};
  observations.reserve(static_cast<std::size_t>(sampled) * used_images.size());
  for (const auto& cand : candidates) {
    const std::size_t before = observations.size();
    for (int j : used_images)
      if (unclipped(j, cand.row, cand.col))
        observations.push_back({j, mean[static_cast<std::size_t>(j)].at<float>(cand.row, cand.col) / 255.0});
    if (static_cast<int>(observations.size() - before) < min_observations)
      observations.resize(before);
    else
      point_begin.push_back(static_cast<int>(observations.size()));
  }
  const int points = static_cast<int>(point_begin.size()) - 1;
  const int nobs = static_cast<int>(observations.size());
  result.point_count = points;
  result.observation_count = nobs;
  if (points < options.min_points)
    return degenerate(result, options,
                      "too few unclipped tracks: " + std::to_string(points) + " points seen in >= " +
                          std::to_string(min_observations) + " images, need " + std::to_string(options.min_points));
  const auto first = [&](int i) { return point_begin[static_cast<std::size_t>(i)]; };
  const auto last = [&](int i) { return point_begin[static_cast<std::size_t>(i) + 1]; };
  const auto observation = [&](int k) -> const Observation& { return observations[static_cast<std::size_t>(k)]; };

  // ---- parameters: c; per image log e_j (estimated or known) or, with the ambient term, the
  // lamp's and the ambient's exposure relative to the reference image, q_j and s_j; per point
  // the log radiance l_i and (ambient term) b_i, the ambient radiance in units of the lamp's at
  // the reference image: X_ij = exp(l_i) (q_j + b_i s_j). b_i may go below 0 as long as every
  // observed X_ij stays positive: estimated per point with noise, a b_i held at >= 0 comes out
  // positive on average where there is no ambient light, and the response bends to match
  // (measured: 0.03 -> 0.10 grey levels in the room, 0.17 -> 3.5 in the tunnel).
  Eigen::Vector4d c = options.prior.coefficients();
  const Eigen::Vector4d c_prior = c;
  std::vector<double> log_exposure(static_cast<std::size_t>(n), 0.0);
  std::vector<double> lamp_scale(static_cast<std::size_t>(n), 0.0), ambient_scale(static_cast<std::size_t>(n), 0.0);
  std::vector<int> exposure_index(static_cast<std::size_t>(n), -1);  // position in the global block
  int globals = 4;
  if (known) {
    const double t_ref = lamp_exposure(reference);
    for (int j = 0; j < n; ++j) {
      lamp_scale[static_cast<std::size_t>(j)] = lamp_exposure(j) / t_ref;
      log_exposure[static_cast<std::size_t>(j)] = lamp_on(j) ? std::log(lamp_exposure(j) / t_ref) : 0.0;
      if (ambient) ambient_scale[static_cast<std::size_t>(j)] = ambient_exposure(j) / ambient_exposure(reference);
    }
  } else {
    for (int j : used_images)
      if (j != reference) exposure_index[static_cast<std::size_t>(j)] = globals++;
  }
  // log X_ij and d log X_ij / d b_i.
  const auto log_irradiance = [&](int j, double l, double b, const std::vector<double>& s, double* d_b) {
    const auto sj = static_cast<std::size_t>(j);
    if (!ambient) {
      if (d_b != nullptr) *d_b = 0.0;
      return l + s[sj];
    }
    return power_sweep_log_irradiance(l, b, lamp_scale[sj], ambient_scale[sj], d_b);
  };

  // Initialisation (Debevec-like, log domain, prior response): log X_ij = l_i + s_j by
  // alternating means; with the ambient term per point X_ij = L_i q_j + A_i s_j by linear least
  // squares on the lamp-lit and lamp-off observations.
  std::vector<double> log_x(static_cast<std::size_t>(nobs));
  for (int k = 0; k < nobs; ++k) {
    const double y = std::clamp(observation(k).grey, 0.5 / 255.0, 1.0 - 0.5 / 255.0);
    log_x[static_cast<std::size_t>(k)] = std::log(std::max(options.prior.inverse(y), 1e-6));
  }
  std::vector<double> log_radiance(static_cast<std::size_t>(points), 0.0);
  std::vector<double> ambient_radiance(static_cast<std::size_t>(points), 0.0);
  // Per point the smallest b_i keeping each of its observations' irradiance positive.
  std::vector<double> min_ambient(static_cast<std::size_t>(points), -kMaxAmbient);
  std::vector<double> sum(static_cast<std::size_t>(n)), count(static_cast<std::size_t>(n));
  if (ambient) {
    for (int i = 0; i < points; ++i) {
      Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
      Eigen::Vector2d right = Eigen::Vector2d::Zero();
      double lamp_only = 0.0, lamp_weight = 0.0;
      for (int k = first(i); k < last(i); ++k) {
        const auto j = static_cast<std::size_t>(observation(k).image);
        const Eigen::Vector2d a(lamp_scale[j], ambient_scale[j]);
        const double x = std::exp(log_x[static_cast<std::size_t>(k)]);
        normal.noalias() += a * a.transpose();
        right.noalias() += a * x;
        lamp_only += lamp_scale[j] * x;
        lamp_weight += lamp_scale[j] * lamp_scale[j];
      }
      double lowest = kMaxAmbient;  // min over the observations of q_j / s_j
      for (int k = first(i); k < last(i); ++k) {
        const auto j = static_cast<std::size_t>(observation(k).image);
        lowest = std::min(lowest, lamp_scale[j] / ambient_scale[j]);
      }
      const auto si = static_cast<std::size_t>(i);
      // A point seen with the lamp off (q_j = 0) shows its ambient light, so it has some.
      min_ambient[si] = lowest > 0.0 ? -0.99 * lowest : 1e-6;
      Eigen::Vector2d la = normal.ldlt().solve(right);
      if (!la.allFinite() || la[0] <= 0.0) la = Eigen::Vector2d(lamp_only / std::max(lamp_weight, 1e-12), 0.0);
      la[0] = std::max(la[0], 1e-6);
      log_radiance[si] = std::log(la[0]);
      // Started at >= 0: under the prior response a negative share is the response's error.
      ambient_radiance[si] = std::clamp(la[1] / la[0], std::max(0.0, min_ambient[si]), kMaxAmbient);
    }
  } else {
    for (int pass = 0; pass < (known ? 1 : 30); ++pass) {
      for (int i = 0; i < points; ++i) {
        double acc = 0.0;
        for (int k = first(i); k < last(i); ++k)
          acc += log_x[static_cast<std::size_t>(k)] - log_exposure[static_cast<std::size_t>(observation(k).image)];
        log_radiance[static_cast<std::size_t>(i)] = acc / (last(i) - first(i));
      }
      if (known) break;
      std::fill(sum.begin(), sum.end(), 0.0);
      std::fill(count.begin(), count.end(), 0.0);
      for (int i = 0; i < points; ++i)
        for (int k = first(i); k < last(i); ++k) {
          const auto j = static_cast<std::size_t>(observation(k).image);
          sum[j] += log_x[static_cast<std::size_t>(k)] - log_radiance[static_cast<std::size_t>(i)];
          count[j] += 1.0;
        }
      for (int j : used_images)
        if (j != reference && count[static_cast<std::size_t>(j)] > 0.0)
          log_exposure[static_cast<std::size_t>(j)] = sum[static_cast<std::size_t>(j)] / count[static_cast<std::size_t>(j)];
    }
  }
  if (!known) {
    double s_min = 0.0, s_max = 0.0;
    for (int j : used_images) {
      s_min = std::min(s_min, log_exposure[static_cast<std::size_t>(j)]);
      s_max = std::max(s_max, log_exposure[static_cast<std::size_t>(j)]);
    }
    if (s_max - s_min < std::log(1.02))
      return degenerate(result, options, "no exposure variation: the usable images are equally bright");
  }

  // ---- Levenberg-Marquardt, Schur complement over the per-point blocks (l_i, beta_i); without
  // the ambient term beta_i is inert (unit diagonal, no gradient).
  const double delta = options.huber_grey / 255.0;
  const double prior_weight = options.coefficient_prior_weight * nobs;
  const double monotonic_weight = 100.0 * nobs;

  const auto total_cost = [&](const Eigen::Vector4d& cc, const std::vector<double>& s, const std::vector<double>& l,
                              const std::vector<double>& beta) {
    double cost = 0.0;
    for (int i = 0; i < points; ++i)
      for (int k = first(i); k < last(i); ++k) {
        const Observation& o = observation(k);
        const double log_x_ij =
            log_irradiance(o.image, l[static_cast<std::size_t>(i)], beta[static_cast<std::size_t>(i)], s, nullptr);
        cost += twice_huber_loss(sweep_prediction(cc, log_x_ij) - o.grey, delta);
      }
    cost += prior_weight * (cc - c_prior).squaredNorm();
    Eigen::Vector4d h, dh;
    for (int g = 0; g < kMonotonicGrid; ++g) {
      response_basis_in_sqrt_irradiance(static_cast<double>(g) / (kMonotonicGrid - 1), h, dh);
      const double slope = 1.0 + cc.dot(dh);
      if (slope < kMinSlope) cost += monotonic_weight * (slope - kMinSlope) * (slope - kMinSlope);
    }
    return cost;
  };

  Eigen::MatrixXd H_gg(globals, globals), S(globals, globals), H_gp(globals, 2 * points);
  Eigen::VectorXd b_g(globals), rhs(globals), J_g(globals), dg(globals);
  std::vector<Eigen::Matrix2d> H_pp(static_cast<std::size_t>(points));
  std::vector<Eigen::Vector2d> b_p(static_cast<std::size_t>(points));
  std::vector<double> trial_s(log_exposure), trial_l(log_radiance), trial_b(ambient_radiance);
  Eigen::Matrix<double, 5, 1> jac;
  double cost = total_cost(c, log_exposure, log_radiance, ambient_radiance);
  double lambda = 1e-4;
  int iteration = 0;
  // The damped point block and its inverse, as the Schur complement and the back substitution use it.
  const auto damped_inverse = [&](int i) {
    Eigen::Matrix2d block = H_pp[static_cast<std::size_t>(i)];
    block.diagonal() *= 1.0 + lambda;
    block.diagonal().array() += 1e-12;
    return Eigen::Matrix2d(block.inverse());
  };
  for (; iteration < options.max_iterations; ++iteration) {
    // Linearise.
    H_gg.setZero();
    b_g.setZero();
    H_gp.setZero();
    for (int i = 0; i < points; ++i) {
      Eigen::Matrix2d hpp = Eigen::Matrix2d::Zero();
      Eigen::Vector2d bp = Eigen::Vector2d::Zero();
      for (int k = first(i); k < last(i); ++k) {
        const Observation& o = observation(k);
        double d_beta = 0.0;
        const double log_x_ij = log_irradiance(o.image, log_radiance[static_cast<std::size_t>(i)],
                                               ambient_radiance[static_cast<std::size_t>(i)], log_exposure, &d_beta);
        const double r = sweep_prediction(c, log_x_ij, &jac) - o.grey;
        const double w = huber_weight(r, delta);
        J_g.setZero();
        J_g.head<4>() = jac.head<4>();
        const int e = exposure_index[static_cast<std::size_t>(o.image)];
        if (e >= 0) J_g[e] = jac[4];
        const Eigen::Vector2d J_p(jac[4], jac[4] * d_beta);
        H_gg.noalias() += w * J_g * J_g.transpose();
        b_g.noalias() += w * r * J_g;
        H_gp.middleCols<2>(2 * i).noalias() += w * J_g * J_p.transpose();
        hpp.noalias() += w * J_p * J_p.transpose();
        bp.noalias() += w * r * J_p;
      }
      if (!ambient) hpp(1, 1) = 1.0;
      H_pp[static_cast<std::size_t>(i)] = hpp;
      b_p[static_cast<std::size_t>(i)] = bp;
    }
    H_gg.topLeftCorner<4, 4>().diagonal().array() += prior_weight;
    b_g.head<4>() += prior_weight * (c - c_prior);
    {
      Eigen::Vector4d h, dh;
      for (int g = 0; g < kMonotonicGrid; ++g) {
        response_basis_in_sqrt_irradiance(static_cast<double>(g) / (kMonotonicGrid - 1), h, dh);
        const double slope = 1.0 + c.dot(dh);
        if (slope < kMinSlope) {
          H_gg.topLeftCorner<4, 4>().noalias() += monotonic_weight * dh * dh.transpose();
          b_g.head<4>() += monotonic_weight * (slope - kMinSlope) * dh;
        }
      }
    }

    if (options.fix_response) {  // c stays at the prior: decouple it and give it a zero step
      H_gg.topRows<4>().setZero();
      H_gg.leftCols<4>().setZero();
      H_gg.topLeftCorner<4, 4>().setIdentity();
      b_g.head<4>().setZero();
      H_gp.topRows<4>().setZero();
    }

    // Try steps with growing damping until one lowers the cost.
    bool accepted = false;
    double new_cost = cost;
    for (int attempt = 0; attempt < 10 && !accepted; ++attempt) {
      S = H_gg;
      S.diagonal() += lambda * H_gg.diagonal();
      S.diagonal().array() += 1e-12;
      rhs = -b_g;
      for (int i = 0; i < points; ++i) {
        const Eigen::Matrix2d inverse = damped_inverse(i);
        const auto H_gi = H_gp.middleCols<2>(2 * i);
        S.noalias() -= H_gi * inverse * H_gi.transpose();
        rhs.noalias() += H_gi * (inverse * b_p[static_cast<std::size_t>(i)]);
      }
      dg = S.ldlt().solve(rhs);
      if (!dg.allFinite()) {
        lambda *= 10.0;
        continue;
      }
      const Eigen::Vector4d trial_c = c + dg.head<4>();
      trial_s = log_exposure;
      for (int j = 0; j < n; ++j) {
        const int e = exposure_index[static_cast<std::size_t>(j)];
        if (e >= 0) trial_s[static_cast<std::size_t>(j)] += dg[e];
      }
      for (int i = 0; i < points; ++i) {
        const auto si = static_cast<std::size_t>(i);
        const Eigen::Vector2d dp = -damped_inverse(i) * (b_p[si] + H_gp.middleCols<2>(2 * i).transpose() * dg);
        trial_l[si] = log_radiance[si] + std::clamp(dp[0], -2.0, 2.0);
        trial_b[si] = ambient ? std::clamp(ambient_radiance[si] + dp[1], min_ambient[si], kMaxAmbient) : ambient_radiance[si];
      }
      new_cost = total_cost(trial_c, trial_s, trial_l, trial_b);
      if (std::isfinite(new_cost) && new_cost < cost) {
        accepted = true;
        c = trial_c;
        log_exposure.swap(trial_s);
        log_radiance.swap(trial_l);
        ambient_radiance.swap(trial_b);
        lambda = std::max(lambda / 3.0, 1e-9);
      } else {
        lambda *= 4.0;
      }
    }
    if (!accepted) break;
    const double decrease = cost - new_cost;
    cost = new_cost;
    if (decrease < 1e-10 * cost) break;
  }
  result.iterations = iteration;

  // ---- result
  double squared = 0.0;
  std::fill(sum.begin(), sum.end(), 0.0);
  std::fill(count.begin(), count.end(), 0.0);
  for (int i = 0; i < points; ++i)
    for (int k = first(i); k < last(i); ++k) {
      const Observation& o = observation(k);
      const double log_x_ij = log_irradiance(o.image, log_radiance[static_cast<std::size_t>(i)],
                                             ambient_radiance[static_cast<std::size_t>(i)], log_exposure, nullptr);
      const double r = sweep_prediction(c, log_x_ij) - o.grey;
      squared += r * r;
      sum[static_cast<std::size_t>(o.image)] += r * r;
      count[static_cast<std::size_t>(o.image)] += 1.0;
    }
  for (int j = 0; j < n; ++j)
    if (count[static_cast<std::size_t>(j)] > 0.0)
      result.images[static_cast<std::size_t>(j)].residual_rms_grey =
          255.0 * std::sqrt(sum[static_cast<std::size_t>(j)] / count[static_cast<std::size_t>(j)]);
  if (known) {
    // Per image the factor k_j on its given exposure that its own observations fit best under the
    // fitted response and radiances: Gauss-Newton on log k_j with the fit's Huber weights. A
    // wrong exposure is partly absorbed by the joint fit, so k_j understates it somewhat.
    std::vector<double> log_factor(static_cast<std::size_t>(n), 0.0);
    for (int step = 0; step < 8; ++step) {
      std::fill(sum.begin(), sum.end(), 0.0);      // J^T W r
      std::fill(count.begin(), count.end(), 0.0);  // J^T W J
      for (int i = 0; i < points; ++i)
        for (int k = first(i); k < last(i); ++k) {
          const Observation& o = observation(k);
          const auto j = static_cast<std::size_t>(o.image);
          const double log_x_ij = log_irradiance(o.image, log_radiance[static_cast<std::size_t>(i)],
                                                 ambient_radiance[static_cast<std::size_t>(i)], log_exposure, nullptr);
          Eigen::Matrix<double, 5, 1> jacobian;
          const double r = sweep_prediction(c, log_x_ij + log_factor[j], &jacobian) - o.grey;
          const double w = huber_weight(r, delta);
          sum[j] += w * jacobian[4] * r;
          count[j] += w * jacobian[4] * jacobian[4];
        }
      for (int j = 0; j < n; ++j)
        if (count[static_cast<std::size_t>(j)] > 0.0)
          log_factor[static_cast<std::size_t>(j)] -= sum[static_cast<std::size_t>(j)] / count[static_cast<std::size_t>(j)];
    }
    // An image is named when it disagrees by more than the tolerance and by more than the sweep's
    // images scatter among themselves: where the response model does not fit a camera closely
    // (the real Canon stack at full size: 7.7 grey levels rms, its shutter times right), the
    // factors wander by 10-27 %, and that says nothing about any one exposure.
    std::vector<double> logs;
    for (int j : used_images)
      if (std::isfinite(log_factor[static_cast<std::size_t>(j)])) logs.push_back(log_factor[static_cast<std::size_t>(j)]);
    double threshold = std::log(kReportedExposureTolerance), centre = 0.0;
    if (!logs.empty()) {
      centre = median_of(logs);
      std::vector<double> deviations;
      for (double l : logs) deviations.push_back(std::abs(l - centre));
      threshold = std::max(threshold, kReportedExposureOutlierSigmas * 1.4826 * median_of(deviations));
    }
    std::string disagreeing;
    for (int j : used_images) {
      const double log_k = log_factor[static_cast<std::size_t>(j)];
      if (!std::isfinite(log_k)) continue;
      result.images[static_cast<std::size_t>(j)].brightness_exposure_factor = std::exp(log_k);
      if (std::abs(log_k) > std::log(kReportedExposureTolerance) && std::abs(log_k - centre) > threshold) {
        result.images[static_cast<std::size_t>(j)].brightness_disagrees = true;
        disagreeing += fmt::format("{}image {} ({:.2f}x)", disagreeing.empty() ? "" : ", ", j, std::exp(log_k));
      }
    }
    if (!disagreeing.empty())
      result.reported_exposure_check = fmt::format(
          "{}: the brightness says this factor times the given exposure (x power for a power sweep); a camera "
          "that reports its exposure control's value rather than the frame's own (read back late, or applied "
          "frames later) does this, and it bends the response: leave such images out, or give their true exposures",
          disagreeing);
  }
  const double rms = 255.0 * std::sqrt(squared / nobs);
  bool finite = std::isfinite(rms) && c.allFinite();
  for (double s : log_exposure) finite = finite && std::isfinite(s);
  if (!finite) return degenerate(result, options, "the fit diverged (non-finite values)");

  if (ambient) {
    // Where the ambient light outshines the lamp the images hardly change and nothing pins f: the
    // median over the points of how much their irradiance changed over the sweep.
    // The fit can also flatten f to match images that do not change, so the grey values' own
    // change over the sweep is checked as well.
    std::vector<double> spans, grey_spans;
    spans.reserve(static_cast<std::size_t>(points));
    grey_spans.reserve(static_cast<std::size_t>(points));
    for (int i = 0; i < points; ++i) {
      double lowest = 1e300, highest = -1e300, darkest = 1.0, brightest = 0.0;
      for (int k = first(i); k < last(i); ++k) {
        const double log_x_ij = log_irradiance(observation(k).image, log_radiance[static_cast<std::size_t>(i)],
                                               ambient_radiance[static_cast<std::size_t>(i)], log_exposure, nullptr);
        lowest = std::min(lowest, log_x_ij);
        highest = std::max(highest, log_x_ij);
        darkest = std::min(darkest, observation(k).grey);
        brightest = std::max(brightest, observation(k).grey);
      }
      spans.push_back(highest - lowest);
      grey_spans.push_back(255.0 * (brightest - darkest));
    }
    constexpr double kMinIrradianceRatio = 1.5;
    constexpr double kMinGreySpan = 8.0;
    const double ratio = std::exp(median_in_place(spans));
    const double grey_span = median_in_place(grey_spans);
    if (!(ratio >= kMinIrradianceRatio) || !(grey_span >= kMinGreySpan))
      return degenerate(result, options,
                        fmt::format("the lamp changes the points by a median {:.1f} grey levels, their irradiance by a "
                                    "factor of {:.2f}, over the sweep (need {:.0f} and {:.1f}; other light outshines "
                                    "it, or the lamp did not change): the response is not determined",
                                    grey_span, ratio, kMinGreySpan, kMinIrradianceRatio));
  }

  {
    std::vector<double> greys;
    greys.reserve(observations.size());
    for (const Observation& o : observations) greys.push_back(o.grey);
    const auto top = greys.begin() + static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(greys.size() - 1));
    std::nth_element(greys.begin(), top, greys.end());
    result.highest_grey = 255.0 * *top;
  }
  const ResponseModel estimate(c);
  result.monotonic = estimate.is_monotonic();
  result.residual_rms_grey = rms;
  if (!result.monotonic) {
    ExposureSweepResult kept = degenerate(result, options, "the fitted response is not monotonic");
    kept.residual_rms_grey = rms;
    kept.monotonic = false;
    return kept;
  }
  result.ok = true;
  result.response = estimate;
  const double e_ref = known ? lamp_exposure(reference) : 1.0;
  for (int j = 0; j < n; ++j) {
    auto& info = result.images[static_cast<std::size_t>(j)];
    if (known) {
      info.ratio = info.exposure / e_ref;
    } else if (info.used) {
      info.exposure = std::exp(log_exposure[static_cast<std::size_t>(j)]);
      info.ratio = info.exposure;
    }
  }
  if (ambient) {
    // Ambient over lamp irradiance at the weakest lit image w: b_i s_w / q_w, median over points.
    int weakest = reference;
    for (int j : used_images)
      if (lamp_on(j) && lamp_scale[static_cast<std::size_t>(j)] < lamp_scale[static_cast<std::size_t>(weakest)]) weakest = j;
    const auto w = static_cast<std::size_t>(weakest);
    std::vector<double> shares;
    shares.reserve(static_cast<std::size_t>(points));
    for (double b : ambient_radiance) shares.push_back(b * ambient_scale[w] / lamp_scale[w]);
    result.ambient_share_at_weakest = median_in_place(shares);
    result.weakest_image = weakest;
  }
  return result;
}

}  // namespace

double sweep_exposure_factor(const ExposureSweepResult& result) {
  if (!result.ok || result.highest_grey >= kSweepAdvisedHighestGrey) return 1.0;
  return exposure_factor_to_reach(result.response, result.highest_grey, kSweepTargetHighestGrey);
}

std::string sweep_range_advice(const ExposureSweepResult& result) {
  if (!result.ok || result.highest_grey >= kSweepAdvisedHighestGrey) return {};
  return fmt::format("the sweep's images reach grey {:.0f} at most (1 % of the samples): above it the response is "
                     "extrapolated and its scale with it; sweep again with about {:.1f}x the exposure or gain, so that "
                     "the strongest setting takes the brightest surfaces near grey {:.0f}",
                     result.highest_grey, sweep_exposure_factor(result), kSweepTargetHighestGrey);
}

ExposureSweepResult calibrate_exposure_sweep(const std::vector<cv::Mat>& images,
                                             const std::optional<std::vector<double>>& exposure_times,
                                             const ExposureSweepOptions& options) {
  const std::optional<std::vector<double>> no_ambient;
  return fit_sweep(images, {exposure_times, no_ambient}, options);
}

ExposureSweepResult calibrate_power_sweep(const std::vector<cv::Mat>& images, const std::vector<PowerSweepFrame>& frames,
                                          bool model_ambient, const ExposureSweepOptions& options) {
  ExposureSweepResult result;
  result.images.resize(images.size());
  if (frames.size() != images.size())
    return degenerate(result, options,
                      "got " + std::to_string(frames.size()) + " powers and exposures for " +
                          std::to_string(images.size()) + " images");
  for (std::size_t j = 0; j < frames.size(); ++j)
    if (!std::isfinite(frames[j].power_w) || frames[j].power_w < 0.0 || !std::isfinite(frames[j].exposure) ||
        frames[j].exposure <= 0.0)
      return degenerate(result, options,
                        "image " + std::to_string(j) + ": the power is negative or the exposure not positive");
  std::optional<std::vector<double>> lamp(std::in_place), ambient;
  if (model_ambient) ambient.emplace();
  std::vector<cv::Mat> fitted;
  std::vector<int> fitted_index;
  for (std::size_t j = 0; j < images.size(); ++j) {
    // Without the ambient term a lamp-off image fits nothing the model has.
    if (!model_ambient && frames[j].power_w == 0.0) continue;
    fitted.push_back(images[j]);
    fitted_index.push_back(static_cast<int>(j));
    lamp->push_back(frames[j].power_w * frames[j].exposure);
    if (ambient) ambient->push_back(frames[j].exposure);
  }
  result = fit_sweep(fitted, {lamp, ambient}, options);
  // Back to the caller's image indices; a lamp-off image left out says why.
  std::vector<ExposureSweepImage> all(images.size());
  for (std::size_t j = 0; j < images.size(); ++j)
    if (frames[j].power_w == 0.0 && !model_ambient) all[j].note = "0 W: ambient light only, outside the model";
  for (std::size_t k = 0; k < fitted_index.size() && k < result.images.size(); ++k)
    all[static_cast<std::size_t>(fitted_index[k])] = result.images[k];
  result.images = std::move(all);
  if (result.reference_image >= 0) result.reference_image = fitted_index[static_cast<std::size_t>(result.reference_image)];
  if (result.weakest_image >= 0) result.weakest_image = fitted_index[static_cast<std::size_t>(result.weakest_image)];
  result.resolution = SweepAmbiguityResolution::IlluminatorPowerSweep;
  return result;
}

double power_sweep_log_irradiance(double log_radiance, double ambient, double lamp_scale, double ambient_scale,
                                  double* d_ambient) {
  const double z = lamp_scale + ambient * ambient_scale;
  if (d_ambient != nullptr) *d_ambient = ambient_scale / z;
  return log_radiance + std::log(z);
}

std::vector<NamedExposureTime> read_exposure_times(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open the exposure-time file");
  std::vector<NamedExposureTime> times;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string_view text = trim(line);
    if (text.empty() || text.front() == '#') continue;
    const auto fields = split_blanks(text);
    if (fields.empty() || fields.front().back() != ':') continue;  // free text
    if (fields.size() != 2) throw InputError(file, number, "expected 'NAME: TIME', got '" + std::string(text) + "'");
    const std::string_view token = fields[1];
    std::optional<double> seconds;
    if (const auto slash = token.find('/'); slash != std::string_view::npos) {
      const auto num = parse_double(token.substr(0, slash));
      const auto den = parse_double(token.substr(slash + 1));
      if (num && den && *den > 0.0) seconds = *num / *den;
    } else {
      seconds = parse_double(token);
    }
    if (!seconds || !(*seconds > 0.0))
      throw InputError(file, number, "exposure time '" + std::string(token) + "' is not a positive number or fraction");
    const std::string_view name = fields.front().substr(0, fields.front().size() - 1);
    if (name.empty()) throw InputError(file, number, "missing image name before ':'");
    times.push_back({std::string(name), *seconds});
  }
  if (times.empty()) throw InputError(file, "no 'NAME: TIME' lines");
  return times;
}

}  // namespace nirslam
