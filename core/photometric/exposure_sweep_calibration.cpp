#include "nirslam/photometric/exposure_sweep_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string_view>

#include <Eigen/Cholesky>
#include <opencv2/imgproc.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/common/huber.hpp"
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

ExposureSweepResult calibrate_exposure_sweep(const std::vector<cv::Mat>& images,
                                             const std::optional<std::vector<double>>& exposure_times,
                                             const ExposureSweepOptions& options) {
  ExposureSweepResult result;
  const int n = static_cast<int>(images.size());
  const bool known = exposure_times.has_value();
  result.resolution = known                   ? SweepAmbiguityResolution::KnownExposureTimes
                      : options.fix_response ? SweepAmbiguityResolution::FixedPriorResponse
                                             : SweepAmbiguityResolution::ReferenceImageNormalisation;
  result.images.resize(static_cast<std::size_t>(n));
  result.response = options.prior;

  // ---- input checks
  if (known) {
    if (static_cast<int>(exposure_times->size()) != n)
      return degenerate(result, options,
                        "got " + std::to_string(exposure_times->size()) + " exposure times for " + std::to_string(n) +
                            " images");
    for (int j = 0; j < n; ++j) {
      const double t = (*exposure_times)[static_cast<std::size_t>(j)];
      if (!std::isfinite(t) || t <= 0.0)
        return degenerate(result, options, "exposure time of image " + std::to_string(j) + " is not positive");
      result.images[static_cast<std::size_t>(j)].exposure = t;
    }
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

  // ---- candidate positions: a grid with ~4x the wanted points, unclipped in >= 2 images,
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
      for (int j = 0; j < n && count < 2; ++j) count += unclipped(j, row, col) ? 1 : 0;
      if (count >= 2) candidates.push_back({row, col, score.at<float>(row, col)});
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
  if (used_images.size() < 2)
    return degenerate(result, options,
                      "fewer than 2 usable images (" + std::to_string(used_images.size()) +
                          "): the others are black or saturated");
  const int reference = used_images.front();
  result.reference_image = reference;

  if (known) {
    double t_min = 1e300, t_max = 0.0;
    for (int j : used_images) {
      t_min = std::min(t_min, (*exposure_times)[static_cast<std::size_t>(j)]);
      t_max = std::max(t_max, (*exposure_times)[static_cast<std::size_t>(j)]);
    }
    if (t_max / t_min < 1.02) return degenerate(result, options, "no exposure variation among the usable images");
  }

  // ---- observations, grouped by point (only points seen unclipped in >= 2 used images)
  std::vector<Observation> observations;
  std::vector<int> point_begin{0};
  observations.reserve(static_cast<std::size_t>(sampled) * used_images.size());
  for (const auto& cand : candidates) {
    const std::size_t before = observations.size();
    for (int j : used_images)
      if (unclipped(j, cand.row, cand.col))
        observations.push_back({j, mean[static_cast<std::size_t>(j)].at<float>(cand.row, cand.col) / 255.0});
    if (observations.size() - before < 2)
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
                      "too few unclipped tracks: " + std::to_string(points) + " points seen in >= 2 images, need " +
                          std::to_string(options.min_points));

  // ---- parameters
  Eigen::Vector4d c = options.prior.coefficients();
  const Eigen::Vector4d c_prior = c;
  std::vector<double> log_exposure(static_cast<std::size_t>(n), 0.0);
  std::vector<int> exposure_index(static_cast<std::size_t>(n), -1);  // position in the global block
  int globals = 4;
  if (known) {
    const double t_ref = (*exposure_times)[static_cast<std::size_t>(reference)];
    for (int j = 0; j < n; ++j) log_exposure[static_cast<std::size_t>(j)] = std::log((*exposure_times)[static_cast<std::size_t>(j)] / t_ref);
  } else {
    for (int j : used_images)
      if (j != reference) exposure_index[static_cast<std::size_t>(j)] = globals++;
  }

  // Initialisation (Debevec-like, log domain, prior response): log X_ij = l_i + s_j by
  // alternating means.
  std::vector<double> log_x(static_cast<std::size_t>(nobs));
  for (int k = 0; k < nobs; ++k) {
    const double y = std::clamp(observations[static_cast<std::size_t>(k)].grey, 0.5 / 255.0, 1.0 - 0.5 / 255.0);
    log_x[static_cast<std::size_t>(k)] = std::log(std::max(options.prior.inverse(y), 1e-6));
  }
  std::vector<double> log_radiance(static_cast<std::size_t>(points), 0.0);
  std::vector<double> sum(static_cast<std::size_t>(n)), count(static_cast<std::size_t>(n));
  for (int pass = 0; pass < (known ? 1 : 30); ++pass) {
    for (int i = 0; i < points; ++i) {
      double acc = 0.0;
      for (int k = point_begin[static_cast<std::size_t>(i)]; k < point_begin[static_cast<std::size_t>(i) + 1]; ++k)
        acc += log_x[static_cast<std::size_t>(k)] - log_exposure[static_cast<std::size_t>(observations[static_cast<std::size_t>(k)].image)];
      log_radiance[static_cast<std::size_t>(i)] = acc / (point_begin[static_cast<std::size_t>(i) + 1] - point_begin[static_cast<std::size_t>(i)]);
    }
    if (known) break;
    std::fill(sum.begin(), sum.end(), 0.0);
    std::fill(count.begin(), count.end(), 0.0);
    for (int i = 0; i < points; ++i)
      for (int k = point_begin[static_cast<std::size_t>(i)]; k < point_begin[static_cast<std::size_t>(i) + 1]; ++k) {
        const auto j = static_cast<std::size_t>(observations[static_cast<std::size_t>(k)].image);
        sum[j] += log_x[static_cast<std::size_t>(k)] - log_radiance[static_cast<std::size_t>(i)];
        count[j] += 1.0;
      }
    for (int j : used_images)
      if (j != reference && count[static_cast<std::size_t>(j)] > 0.0)
        log_exposure[static_cast<std::size_t>(j)] = sum[static_cast<std::size_t>(j)] / count[static_cast<std::size_t>(j)];
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

  // ---- Levenberg-Marquardt, Schur complement over the log radiances
  const double delta = options.huber_grey / 255.0;
  const double prior_weight = options.coefficient_prior_weight * nobs;
  const double monotonic_weight = 100.0 * nobs;

  const auto total_cost = [&](const Eigen::Vector4d& cc, const std::vector<double>& s, const std::vector<double>& l) {
    double cost = 0.0;
    for (int i = 0; i < points; ++i)
      for (int k = point_begin[static_cast<std::size_t>(i)]; k < point_begin[static_cast<std::size_t>(i) + 1]; ++k) {
        const Observation& o = observations[static_cast<std::size_t>(k)];
        const double r = sweep_prediction(cc, l[static_cast<std::size_t>(i)] + s[static_cast<std::size_t>(o.image)]) - o.grey;
        cost += twice_huber_loss(r, delta);
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

  Eigen::MatrixXd H_gg(globals, globals), S(globals, globals), H_gl(globals, points);
  Eigen::VectorXd b_g(globals), rhs(globals), J_g(globals), dg(globals);
  std::vector<double> H_ll(static_cast<std::size_t>(points)), b_l(static_cast<std::size_t>(points));
  std::vector<double> trial_s(log_exposure), trial_l(log_radiance);
  Eigen::Matrix<double, 5, 1> jac;
  double cost = total_cost(c, log_exposure, log_radiance);
  double lambda = 1e-4;
  int iteration = 0;
  for (; iteration < options.max_iterations; ++iteration) {
    // Linearise.
    H_gg.setZero();
    b_g.setZero();
    H_gl.setZero();
    for (int i = 0; i < points; ++i) {
      double hll = 0.0, bl = 0.0;
      for (int k = point_begin[static_cast<std::size_t>(i)]; k < point_begin[static_cast<std::size_t>(i) + 1]; ++k) {
        const Observation& o = observations[static_cast<std::size_t>(k)];
        const double r =
            sweep_prediction(c, log_radiance[static_cast<std::size_t>(i)] + log_exposure[static_cast<std::size_t>(o.image)], &jac) - o.grey;
        const double w = huber_weight(r, delta);
        J_g.setZero();
        J_g.head<4>() = jac.head<4>();
        const int e = exposure_index[static_cast<std::size_t>(o.image)];
        if (e >= 0) J_g[e] = jac[4];
        H_gg.noalias() += w * J_g * J_g.transpose();
        b_g.noalias() += w * r * J_g;
        H_gl.col(i).noalias() += w * jac[4] * J_g;
        hll += w * jac[4] * jac[4];
        bl += w * jac[4] * r;
      }
      H_ll[static_cast<std::size_t>(i)] = hll;
      b_l[static_cast<std::size_t>(i)] = bl;
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
      H_gl.topRows<4>().setZero();
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
        const double hll = H_ll[static_cast<std::size_t>(i)] * (1.0 + lambda) + 1e-12;
        S.noalias() -= H_gl.col(i) * H_gl.col(i).transpose() / hll;
        rhs.noalias() += H_gl.col(i) * (b_l[static_cast<std::size_t>(i)] / hll);
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
        const double hll = H_ll[static_cast<std::size_t>(i)] * (1.0 + lambda) + 1e-12;
        const double dl = -(b_l[static_cast<std::size_t>(i)] + H_gl.col(i).dot(dg)) / hll;
        trial_l[static_cast<std::size_t>(i)] = log_radiance[static_cast<std::size_t>(i)] + std::clamp(dl, -2.0, 2.0);
      }
      new_cost = total_cost(trial_c, trial_s, trial_l);
      if (std::isfinite(new_cost) && new_cost < cost) {
        accepted = true;
        c = trial_c;
        log_exposure.swap(trial_s);
        log_radiance.swap(trial_l);
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
    for (int k = point_begin[static_cast<std::size_t>(i)]; k < point_begin[static_cast<std::size_t>(i) + 1]; ++k) {
      const Observation& o = observations[static_cast<std::size_t>(k)];
      const double r = sweep_prediction(c, log_radiance[static_cast<std::size_t>(i)] + log_exposure[static_cast<std::size_t>(o.image)]) - o.grey;
      squared += r * r;
      sum[static_cast<std::size_t>(o.image)] += r * r;
      count[static_cast<std::size_t>(o.image)] += 1.0;
    }
  for (int j = 0; j < n; ++j)
    if (count[static_cast<std::size_t>(j)] > 0.0)
      result.images[static_cast<std::size_t>(j)].residual_rms_grey =
          255.0 * std::sqrt(sum[static_cast<std::size_t>(j)] / count[static_cast<std::size_t>(j)]);
  const double rms = 255.0 * std::sqrt(squared / nobs);
  bool finite = std::isfinite(rms) && c.allFinite();
  for (double s : log_exposure) finite = finite && std::isfinite(s);
  if (!finite) return degenerate(result, options, "the fit diverged (non-finite values)");

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
  const double e_ref = known ? (*exposure_times)[static_cast<std::size_t>(reference)] : 1.0;
  for (int j = 0; j < n; ++j) {
    auto& info = result.images[static_cast<std::size_t>(j)];
    if (known) {
      info.ratio = info.exposure / e_ref;
    } else if (info.used) {
      info.exposure = std::exp(log_exposure[static_cast<std::size_t>(j)]);
      info.ratio = info.exposure;
    }
  }
  return result;
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
