#include "nirslam/photometric/photometric_backend.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <unordered_map>

#include <Eigen/Cholesky>

namespace nirslam {

namespace {

constexpr int kInverseTableSize = 1025;

double huber_cost(double s, double delta) {
  const double a = std::abs(s);
  return a <= delta ? s * s : 2.0 * delta * a - delta * delta;
}
double huber_weight(double s, double delta) {
  const double a = std::abs(s);
  return a <= delta ? 1.0 : delta / a;
}

double f_of_u(const Eigen::Vector4d& c, double u, double* slope) {
  Eigen::Vector4d h, dh;
  response_basis_in_sqrt_irradiance(u, h, dh);
  if (slope != nullptr) *slope = 1.0 + c.dot(dh);
  return u + c.dot(h);
}

double vignette_at(const Eigen::Vector3d& v, double radius) {
  const double r2 = radius * radius;
  return 1.0 + r2 * (v[0] + r2 * (v[1] + r2 * v[2]));
}

double median_in_place(std::vector<double>& values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// V > 0 on [0, 1]: the correction G / V must stay finite. (A beam pattern times a vignette may
// rise slightly off-centre, so monotonic decrease is not required.)
bool vignette_positive(const Eigen::Vector3d& v) {
  const VignetteModel model{v};
  for (int i = 0; i <= 64; ++i)
    if (!(model(i / 64.0) > 0.05)) return false;
  return true;
}

}  // namespace

InverseResponse::InverseResponse(const Eigen::Vector4d& c) : c_(c), table_(kInverseTableSize) {
  // Walk a fine grid of u once; f is increasing, so each y's bracket follows the previous one.
  constexpr int kGrid = 4 * (kInverseTableSize - 1);
  int j = 0;
  double f_lo = 0.0, f_hi = f_of_u(c_, 1.0 / kGrid, nullptr);
  for (int i = 0; i < kInverseTableSize; ++i) {
    const double y = static_cast<double>(i) / (kInverseTableSize - 1);
    while (j < kGrid - 1 && f_hi < y) {
      ++j;
      f_lo = f_hi;
      f_hi = f_of_u(c_, static_cast<double>(j + 1) / kGrid, nullptr);
    }
    const double t = f_hi > f_lo ? std::clamp((y - f_lo) / (f_hi - f_lo), 0.0, 1.0) : 0.0;
    table_[static_cast<std::size_t>(i)] = (j + t) / kGrid;
  }
}

double InverseResponse::sqrt_irradiance(double y) const {
  y = std::clamp(y, 0.0, 1.0);
  const double position = y * (kInverseTableSize - 1);
  const int i = std::min(static_cast<int>(position), kInverseTableSize - 2);
  const double t = position - i;
  double u = (1.0 - t) * table_[static_cast<std::size_t>(i)] + t * table_[static_cast<std::size_t>(i) + 1];
  for (int iteration = 0; iteration < 2; ++iteration) {
    double slope = 0.0;
    const double f = f_of_u(c_, u, &slope);
    if (!(slope > 1e-9)) break;
    u = std::clamp(u - (f - y) / slope, 0.0, 1.0);
  }
  return u;
}

double photometric_residual(const InverseResponse& inverse, const Eigen::Vector3d& v, double exposure,
                            double radiance, double grey, double radius, PhotometricJacobian* jacobian,
                            double* irradiance, double* grey_per_irradiance) {
  const double u = inverse.sqrt_irradiance(grey / 255.0);
  const double G = 255.0 * u * u;
  const double r2 = radius * radius;
  const double V = 1.0 + r2 * (v[0] + r2 * (v[1] + r2 * v[2]));
  const double eV = exposure * V;
  if (irradiance != nullptr) *irradiance = G;
  if (jacobian != nullptr || grey_per_irradiance != nullptr) {
    Eigen::Vector4d h, dh;
    response_basis_in_sqrt_irradiance(u, h, dh);
    const double slope = 1.0 + inverse.coefficients().dot(dh);
    // dI/dG = df/dX = f'(u) / (2u) (both in grey levels); u > 0 for any unclipped grey value.
    if (grey_per_irradiance != nullptr) *grey_per_irradiance = slope / (2.0 * std::max(u, 1e-6));
    if (jacobian == nullptr) return G / eV - radiance;
    // dG/dc_k = 255 dX/dc_k = 255 * 2u * du/dc_k, du/dc_k = -h_k(u) / f'(u) (implicit function).
    jacobian->head<4>() = (-255.0 * 2.0 * u / (slope * eV)) * h;
    const double dV = -G / (eV * V);  // dr/dV
    (*jacobian)[4] = dV * r2;
    (*jacobian)[5] = dV * r2 * r2;
    (*jacobian)[6] = dV * r2 * r2 * r2;
    (*jacobian)[7] = -G / (eV * exposure);
    (*jacobian)[8] = -1.0;
  }
  return G / eV - radiance;
}

PhotometricBackend::PhotometricBackend(PhotometricBackendOptions options)
    : options_(std::move(options)), response_(options_.initial_response), vignette_(options_.initial_vignette) {
  if (!response_.is_monotonic()) throw std::invalid_argument("photometric back end: the initial response is not monotonic");
  if (options_.max_keyframes < 2 || options_.max_stored_keyframes < options_.max_keyframes || options_.max_points < 1)
    throw std::invalid_argument("photometric back end: bad window options");
}

void PhotometricBackend::reset() {
  response_ = options_.initial_response;
  vignette_ = options_.initial_vignette;
  keyframes_.clear();
  added_ = 0;
}

void PhotometricBackend::add_keyframe(PhotometricKeyframe keyframe) {
  if (!(keyframe.exposure > 0.0) || !std::isfinite(keyframe.exposure)) return;
  keyframes_.push_back(std::move(keyframe));
  ++added_;
  if (static_cast<int>(keyframes_.size()) > options_.max_stored_keyframes) {
    // Thin the store evenly (drop every second of the older half) instead of forgetting the
    // start: the batch optimisation wants the whole sequence's exposure and radius coverage,
    // while the newest max_keyframes stay complete for the online window.
    std::deque<PhotometricKeyframe> thinned;
    const std::size_t protect = static_cast<std::size_t>(options_.max_keyframes);
    const std::size_t older = keyframes_.size() - protect;
    for (std::size_t i = 0; i < keyframes_.size(); ++i)
      if (i >= older || i % 2 == 0) thinned.push_back(std::move(keyframes_[i]));
    keyframes_.swap(thinned);
  }
}

std::vector<std::pair<std::int64_t, double>> PhotometricBackend::keyframe_exposures() const {
  std::vector<std::pair<std::int64_t, double>> out;
  out.reserve(keyframes_.size());
  for (const PhotometricKeyframe& k : keyframes_) out.emplace_back(k.frame_index, k.exposure);
  return out;
}

void PhotometricBackend::build_problem(const std::vector<int>& window) {
  points_.clear();
  observations_.clear();
  // Track id -> (window position, observation) over the window.
  std::unordered_map<std::int64_t, std::vector<std::pair<int, const KeyframeObservation*>>> tracks;
  for (int w = 0; w < static_cast<int>(window.size()); ++w)
    for (const KeyframeObservation& o : keyframes_[static_cast<std::size_t>(window[static_cast<std::size_t>(w)])].observations)
      tracks[o.track_id].emplace_back(w, &o);
  std::vector<const std::vector<std::pair<int, const KeyframeObservation*>>*> usable;
  usable.reserve(tracks.size());
  for (const auto& [id, list] : tracks)
    if (static_cast<int>(list.size()) >= options_.min_observations_per_point) usable.push_back(&list);
  // Longest tracks first (most constraints per unknown); ties by first keyframe for determinism.
  std::sort(usable.begin(), usable.end(), [](const auto* a, const auto* b) {
    if (a->size() != b->size()) return a->size() > b->size();
    return (*a)[0].second->track_id < (*b)[0].second->track_id;
  });
  const double mu = options_.gradient_mu;
  for (const auto* list : usable) {
    if (static_cast<int>(points_.size()) + kBackendPixels > options_.max_points) break;
    for (int k = 0; k < kBackendPixels; ++k) {
      Point point;
      point.begin = static_cast<int>(observations_.size());
      for (const auto& [w, o] : *list) {
        const float grey = o->grey[static_cast<std::size_t>(k)];
        if (grey < 0.0f) continue;
        const PhotometricKeyframe& kf = keyframes_[static_cast<std::size_t>(window[static_cast<std::size_t>(w)])];
        const Eigen::Vector2d p = o->position + backend_pixel_offset(k);
        Observation ob;
        ob.keyframe = w;
        ob.grey = grey;
        ob.radius = VignetteModel::radius(p.x(), p.y(), kf.width, kf.height);
        ob.gradient_weight = mu / (mu + static_cast<double>(o->gradient_sq[static_cast<std::size_t>(k)]));
        observations_.push_back(ob);
      }
      point.end = static_cast<int>(observations_.size());
      if (point.end - point.begin >= options_.min_observations_per_point)
        points_.push_back(point);
      else
        observations_.resize(static_cast<std::size_t>(point.begin));
    }
  }
}

void PhotometricBackend::initialise_radiances(const InverseResponse& inverse, const Eigen::Vector3d& v,
                                              const std::vector<double>& exposures, std::vector<Point>& points) const {
  // The weighted least-squares radiance for fixed globals: with weight (eV)^2 on G/(eV) - L,
  // L = sum(eV G) / sum((eV)^2).
  for (Point& p : points) {
    double num = 0.0, den = 0.0;
    for (int i = p.begin; i < p.end; ++i) {
      const Observation& o = observations_[static_cast<std::size_t>(i)];
      double G = 0.0, k = 0.0;
      photometric_residual(inverse, v, 1.0, 0.0, o.grey, o.radius, nullptr, &G, &k);
      const double eV = exposures[static_cast<std::size_t>(o.keyframe)] * vignette_at(v, o.radius);
      num += o.gradient_weight * k * k * eV * G;
      den += o.gradient_weight * k * k * eV * eV;
    }
    p.radiance = den > 0.0 ? num / den : 0.0;
  }
}

double PhotometricBackend::evaluate_cost(const InverseResponse& inverse, const Eigen::Vector3d& v,
                                         const std::vector<double>& exposures, const std::vector<Point>& points,
                                         double delta) const {
  // Scaled residual s = r e V / e_scale = (G - e V L) / e_scale; exposures are pre-divided by e_scale.
  double cost = 0.0;
  for (const Point& p : points)
    for (int i = p.begin; i < p.end; ++i) {
      const Observation& o = observations_[static_cast<std::size_t>(i)];
      const double e = exposures[static_cast<std::size_t>(o.keyframe)];
      double G = 0.0, k = 0.0;
      const double r = photometric_residual(inverse, v, e, p.radiance, o.grey, o.radius, nullptr, &G, &k);
      const double s = r * e * vignette_at(v, o.radius) * k;
      cost += o.gradient_weight * huber_cost(s, delta);
    }
  return cost;
}

BackendStep PhotometricBackend::optimise(int max_iterations, bool all_stored) {
  BackendStep step;
  step.ok = true;
  window_.clear();
  const int stored = static_cast<int>(keyframes_.size());
  const int first = all_stored ? 0 : std::max(0, stored - options_.max_keyframes);
  for (int i = first; i < stored; ++i) window_.push_back(i);
  step.keyframes = static_cast<int>(window_.size());
  if (step.keyframes < options_.min_keyframes) {
    step.status = "waiting for keyframes (" + std::to_string(step.keyframes) + " of " +
                  std::to_string(options_.min_keyframes) + ")";
    return step;
  }
  build_problem(window_);
  step.points = static_cast<int>(points_.size());
  step.observations = static_cast<int>(observations_.size());
  if (step.points < options_.min_points) {
    step.status = "too few points tracked over several keyframes (" + std::to_string(step.points) + " < " +
                  std::to_string(options_.min_points) + "); last estimate kept";
    return step;
  }

  // Exposures, divided by their median so the numbers stay near 1 whatever the unit; free or held.
  const int K = step.keyframes;
  std::vector<double> exposure(static_cast<std::size_t>(K));
  for (int w = 0; w < K; ++w) exposure[static_cast<std::size_t>(w)] = keyframes_[static_cast<std::size_t>(window_[static_cast<std::size_t>(w)])].exposure;
  std::vector<double> sorted = exposure;
  const double e_scale = median_in_place(sorted);
  const double e_min = *std::min_element(exposure.begin(), exposure.end());
  const double e_max = *std::max_element(exposure.begin(), exposure.end());
  for (double& e : exposure) e /= e_scale;
  std::vector<int> free_index(static_cast<std::size_t>(K), -1);
  int globals = 7;
  bool any_fixed = false;
  for (int w = 0; w < K; ++w)
    any_fixed |= options_.trust_known_exposures && keyframes_[static_cast<std::size_t>(window_[static_cast<std::size_t>(w)])].exposure_known;
  for (int w = 0; w < K; ++w) {
    const bool known = options_.trust_known_exposures && keyframes_[static_cast<std::size_t>(window_[static_cast<std::size_t>(w)])].exposure_known;
    // Without any reported exposure, the oldest keyframe of the window is the gauge.
    if (known || (!any_fixed && w == 0)) continue;
    free_index[static_cast<std::size_t>(w)] = globals++;
  }

  // Observability: the response needs the same points under different exposures, the vignette
  // the same points at different radii.
  step.response_estimated = options_.estimate_response && e_max / e_min >= options_.min_exposure_ratio;
  {
    int moving = 0;
    for (const Point& p : points_) {
      double lo = 2.0, hi = -1.0;
      for (int i = p.begin; i < p.end; ++i) {
        lo = std::min(lo, observations_[static_cast<std::size_t>(i)].radius);
        hi = std::max(hi, observations_[static_cast<std::size_t>(i)].radius);
      }
      moving += hi - lo >= options_.min_radius_span;
    }
    step.vignette_estimated = options_.estimate_vignette && moving >= options_.min_points / 2;
  }
  std::string held;
  if (!step.response_estimated)
    held += options_.estimate_response ? "response held (exposure varies too little: " +
                                             std::to_string(e_max / e_min).substr(0, 4) + "x)"
                                       : "response held (fixed)";
  if (!step.vignette_estimated)
    held += std::string(held.empty() ? "" : "; ") +
            (options_.estimate_vignette ? "vignette held (points move too little across the image)" : "vignette held (fixed)");
  if (!step.response_estimated && !step.vignette_estimated && globals == 7) {
    step.status = "nothing observable: " + held + "; last estimate kept";
    return step;
  }

  Eigen::Vector4d c = response_.coefficients();
  Eigen::Vector3d v = vignette_.v;
  const Eigen::Vector4d c_prior = options_.initial_response.coefficients();
  InverseResponse inverse(c);
  initialise_radiances(inverse, v, exposure, points_);

  // Huber width from the robust spread of the scaled residuals at the start.
  double delta = 1.0;
  {
    std::vector<double> abs_s;
    abs_s.reserve(observations_.size());
    for (const Point& p : points_)
      for (int i = p.begin; i < p.end; ++i) {
        const Observation& o = observations_[static_cast<std::size_t>(i)];
        double G = 0.0, k = 0.0;
        const double r = photometric_residual(inverse, v, exposure[static_cast<std::size_t>(o.keyframe)], p.radiance,
                                              o.grey, o.radius, nullptr, &G, &k);
        abs_s.push_back(std::abs(r * exposure[static_cast<std::size_t>(o.keyframe)] * vignette_at(v, o.radius) * k));
      }
    delta = options_.huber_k * std::max(1.4826 * median_in_place(abs_s), 0.5);
  }
  const double nobs = static_cast<double>(observations_.size());
  const double prior_weight = options_.coefficient_prior_weight * nobs;
  const auto total_cost = [&](const InverseResponse& inv, const Eigen::Vector4d& cc, const Eigen::Vector3d& vv,
                              const std::vector<double>& ee, const std::vector<Point>& pp) {
    return evaluate_cost(inv, vv, ee, pp, delta) + prior_weight * (cc - c_prior).squaredNorm();
  };
  double cost = total_cost(inverse, c, v, exposure, points_);
  if (!std::isfinite(cost)) {
    step.ok = false;
    step.status = "cost not finite at the start; last estimate kept";
    return step;
  }

  Eigen::MatrixXd H(globals, globals), S(globals, globals);
  Eigen::VectorXd b(globals), rhs(globals), dx(globals);
  std::vector<double> h_pp(points_.size()), b_p(points_.size());
  std::vector<Eigen::Matrix<double, 7, 1>> h_pg(points_.size());
  std::vector<double> h_pe(observations_.size());  // coupling of each observation's point with its exposure
  std::vector<Point> trial_points = points_;
  std::vector<double> trial_exposure = exposure;
  std::vector<int> index;
  std::vector<double> value;
  PhotometricJacobian J;
  double lambda = 1e-3;
  int iteration = 0;
  for (; iteration < max_iterations; ++iteration) {
    H.setZero();
    b.setZero();
    for (std::size_t pi = 0; pi < points_.size(); ++pi) {
      const Point& p = points_[pi];
      double hpp = 0.0, bp = 0.0;
      Eigen::Matrix<double, 7, 1> hpg = Eigen::Matrix<double, 7, 1>::Zero();
      for (int i = p.begin; i < p.end; ++i) {
        const Observation& o = observations_[static_cast<std::size_t>(i)];
        const double e = exposure[static_cast<std::size_t>(o.keyframe)];
        double G = 0.0, k = 0.0;
        const double r = photometric_residual(inverse, v, e, p.radiance, o.grey, o.radius, &J, &G, &k);
        const double eVk = e * vignette_at(v, o.radius) * k;
        const double s = r * eVk;
        const double w = o.gradient_weight * eVk * eVk * huber_weight(s, delta);
        Eigen::Matrix<double, 7, 1> jg = J.head<7>();
        if (!step.response_estimated) jg.head<4>().setZero();
        if (!step.vignette_estimated) jg.tail<3>().setZero();
        H.topLeftCorner<7, 7>().noalias() += w * jg * jg.transpose();
        b.head<7>() += (w * r) * jg;
        const int fe = free_index[static_cast<std::size_t>(o.keyframe)];
        if (fe >= 0) {
          H.block<7, 1>(0, fe) += (w * J[7]) * jg;
          H(fe, fe) += w * J[7] * J[7];
          b[fe] += w * r * J[7];
        }
        // dr/dL = -1.
        hpp += w;
        bp -= w * r;
        hpg -= w * jg;
        h_pe[static_cast<std::size_t>(i)] = fe >= 0 ? -w * J[7] : 0.0;
      }
      h_pp[pi] = hpp;
      b_p[pi] = bp;
      h_pg[pi] = hpg;
    }
    for (int g = 7; g < globals; ++g) H.block(g, 0, 1, 7) = H.block(0, g, 7, 1).transpose();
    if (step.response_estimated) {
      H.topLeftCorner<4, 4>().diagonal().array() += prior_weight;
      b.head<4>() += prior_weight * (c - c_prior);
    }

    bool accepted = false;
    double new_cost = cost;
    Eigen::Vector4d trial_c = c;
    Eigen::Vector3d trial_v = v;
    for (int attempt = 0; attempt < 8 && !accepted; ++attempt) {
      S = H;
      for (int g = 0; g < globals; ++g) S(g, g) = H(g, g) > 0.0 ? H(g, g) * (1.0 + lambda) : 1.0;
      rhs = -b;
      // Schur complement over the radiances: S -= h_pg h_pg^T / h_pp, over each point's few
      // non-zero entries (c, v and the exposures of its keyframes).
      for (std::size_t pi = 0; pi < points_.size(); ++pi) {
        const Point& p = points_[pi];
        const double d = h_pp[pi] * (1.0 + lambda) + 1e-12;
        index.assign({0, 1, 2, 3, 4, 5, 6});
        value.assign(h_pg[pi].data(), h_pg[pi].data() + 7);
        for (int i = p.begin; i < p.end; ++i) {
          const int fe = free_index[static_cast<std::size_t>(observations_[static_cast<std::size_t>(i)].keyframe)];
          if (fe >= 0) {
            index.push_back(fe);
            value.push_back(h_pe[static_cast<std::size_t>(i)]);
          }
        }
        for (std::size_t a = 0; a < index.size(); ++a) {
          rhs[index[a]] += value[a] * b_p[pi] / d;
          for (std::size_t bb = 0; bb < index.size(); ++bb) S(index[a], index[bb]) -= value[a] * value[bb] / d;
        }
      }
      dx = S.ldlt().solve(rhs);
      if (!dx.allFinite()) {
        lambda *= 10.0;
        continue;
      }
      trial_c = c + dx.head<4>();
      trial_v = v + dx.segment<3>(4);
      bool valid = true;
      for (int w = 0; w < K; ++w) {
        const int fe = free_index[static_cast<std::size_t>(w)];
        trial_exposure[static_cast<std::size_t>(w)] = exposure[static_cast<std::size_t>(w)] + (fe >= 0 ? dx[fe] : 0.0);
        valid &= trial_exposure[static_cast<std::size_t>(w)] > 0.0;
      }
      valid = valid && (!step.response_estimated || ResponseModel(trial_c).is_monotonic()) &&
              (!step.vignette_estimated || vignette_positive(trial_v));
      if (!valid) {
        lambda *= 4.0;
        continue;
      }
      for (std::size_t pi = 0; pi < points_.size(); ++pi) {
        const Point& p = points_[pi];
        const double d = h_pp[pi] * (1.0 + lambda) + 1e-12;
        double coupling = h_pg[pi].dot(dx.head<7>());
        for (int i = p.begin; i < p.end; ++i) {
          const int fe = free_index[static_cast<std::size_t>(observations_[static_cast<std::size_t>(i)].keyframe)];
          if (fe >= 0) coupling += h_pe[static_cast<std::size_t>(i)] * dx[fe];
        }
        trial_points[pi].radiance = p.radiance - (b_p[pi] + coupling) / d;
      }
      const InverseResponse trial_inverse(trial_c);
      new_cost = total_cost(trial_inverse, trial_c, trial_v, trial_exposure, trial_points);
      if (std::isfinite(new_cost) && new_cost < cost) {
        accepted = true;
        c = trial_c;
        v = trial_v;
        inverse = trial_inverse;
        exposure.swap(trial_exposure);
        points_.swap(trial_points);
        lambda = std::max(lambda / 3.0, 1e-9);
      } else {
        lambda *= 4.0;
      }
    }
    if (!accepted) {
      step.converged = true;  // no step lowers the cost any more
      break;
    }
    const double decrease = cost - new_cost;
    cost = new_cost;
    if (decrease < options_.convergence_relative * cost) {
      step.converged = true;
      ++iteration;
      break;
    }
  }
  step.iterations = iteration;
  step.cost = cost / nobs;
  if (!c.allFinite() || !v.allFinite()) {
    step.ok = false;
    step.status = "optimisation diverged (not finite); last estimate kept";
    return step;
  }
  step.updated = iteration > 0;
  response_ = ResponseModel(c);
  vignette_.v = v;
  for (int w = 0; w < K; ++w)
    keyframes_[static_cast<std::size_t>(window_[static_cast<std::size_t>(w)])].exposure = exposure[static_cast<std::size_t>(w)] * e_scale;
  {
    double squared = 0.0;
    std::size_t inliers = 0;
    for (const Point& p : points_)
      for (int i = p.begin; i < p.end; ++i) {
        const Observation& o = observations_[static_cast<std::size_t>(i)];
        double G = 0.0, k = 0.0;
        const double r = photometric_residual(inverse, v, exposure[static_cast<std::size_t>(o.keyframe)], p.radiance,
                                              o.grey, o.radius, nullptr, &G, &k);
        const double s = r * exposure[static_cast<std::size_t>(o.keyframe)] * vignette_at(v, o.radius) * k;
        if (std::abs(s) <= delta) squared += s * s, ++inliers;
      }
    step.residual_rms = inliers ? std::sqrt(squared / static_cast<double>(inliers)) : 0.0;
  }
  char text[160];
  std::snprintf(text, sizeof text, "%s after %d iterations (%d keyframes, %d points, residual %.2f grey levels)",
                step.converged ? "converged" : "iterating", step.iterations, step.keyframes, step.points,
                step.residual_rms);
  step.status = text;
  if (!held.empty()) step.status += "; " + held;
  return step;
}

}  // namespace nirslam
