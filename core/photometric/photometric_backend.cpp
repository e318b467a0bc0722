#include "nirslam/photometric/photometric_backend.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <unordered_map>

#include <Eigen/Cholesky>

#include "nirslam/common/huber.hpp"
#include "nirslam/common/median.hpp"

namespace nirslam {

namespace {

constexpr int kInverseTableSize = 1025;

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

// One past the last of the points from `first` on that share its track (a track's pixels are
// adjacent in the point list).
template <typename Points>
std::size_t track_end(const Points& points, std::size_t first) {
  std::size_t last = first;
  while (last < points.size() && points[last].track == points[first].track) ++last;
  return last;
}

// V > 0 on [0, 1]: the correction G / V must stay finite. (A beam pattern times a vignette may
// rise slightly off-centre, so monotonic decrease is not required.)
bool vignette_positive(const Eigen::Vector3d& v) {
  const VignetteModel model{v};
  for (int i = 0; i <= 64; ++i)
    if (!(model(i / 64.0) > 0.05)) return false;
  return true;
}

double f_slope(const Eigen::Vector4d& c, double u) {
  Eigen::Vector4d h, dh;
  response_basis_in_sqrt_irradiance(u, h, dh);
  return 1.0 + c.dot(dh);
}

// The basis derivative at 256 points of u (cell midpoints): f'(u) = 1 + c . dh there, so the
// monotonicity test of a trial step is 256 dot products.
struct MonotonicGrid {
  std::vector<Eigen::Vector4d> dh;
};
const MonotonicGrid& monotonic_grid() {
  static const MonotonicGrid grid = [] {
    MonotonicGrid g;
    constexpr int kPoints = 256;
    g.dh.resize(kPoints);
    for (int i = 0; i < kPoints; ++i) {
      Eigen::Vector4d h;
      response_basis_in_sqrt_irradiance((i + 0.5) / kPoints, h, g.dh[static_cast<std::size_t>(i)]);
    }
    return g;
  }();
  return grid;
}
bool monotonic_on_grid(const Eigen::Vector4d& c) {
  for (const Eigen::Vector4d& dh : monotonic_grid().dh)
    if (!(1.0 + c.dot(dh) > 0.0)) return false;
  return true;
}

// sqrt(X) of a predicted irradiance G = e V a L (grey-level units), X = G / 255 clamped to the
// response's domain; floored above 0, where dI/dG = f'(u) / (2u) has no finite value.
double predicted_sqrt_irradiance(double irradiance_grey) {
  return std::sqrt(std::clamp(irradiance_grey / 255.0, 1e-6, 1.0));
}
// Where predicted_sqrt_irradiance stops at X = 1: nothing moves the prediction there.
bool predicted_above_full_scale(double irradiance_grey) { return irradiance_grey >= 255.0; }

// The predicted grey value at irradiance e V a L (grey-level units), against the observed one:
// u = sqrt(X) where it is linearised, the basis h(u), f'(u) and s = grey - 255 f(u). One formula
// for predicted_grey_residual(), the cost and the LM step.
// With clip_noise_grey > 0 the prediction is the expected value of a sample that did not clip
// (PhotometricBackendOptions::clip_noise_grey), and slope and h carry its derivative in mu.
struct GreyPrediction {
  double u = 0.0, slope = 0.0, s = 0.0;
  Eigen::Vector4d h = Eigen::Vector4d::Zero();
};
// Beyond this many standard deviations below full scale the truncation shifts a sample by less
// than 1e-8 of them.
constexpr double kClipNoiseNegligibleZ = 6.0;
GreyPrediction predict_grey(const Eigen::Vector4d& c, double irradiance_grey, double grey, double clip_noise_grey) {
  GreyPrediction p;
  p.u = predicted_sqrt_irradiance(irradiance_grey);
  Eigen::Vector4d dh;
  response_basis_in_sqrt_irradiance(p.u, p.h, dh);
  p.slope = 1.0 + c.dot(dh);
  const double mu = 255.0 * (p.u + c.dot(p.h));
  p.s = grey - mu;
  // At or above full scale the prediction stops at X = 1 (predicted_sqrt_irradiance): it no longer
  // moves with the irradiance (and h(1) = 0, so not with c either). The basis's slope there would
  // tell the step that lowering the radiance lowers the prediction, and a bright point's samples
  // that read a little under 255 pulled its radiance down by their noise alone (README
  // "Photometric calibration accuracy", session 47).
  if (predicted_above_full_scale(irradiance_grey)) {
    p.slope = 0.0;
    p.h.setZero();
  }
  if (clip_noise_grey > 0.0) {
    // A normal sample is one that did not clip: near full scale its expected value is that of a
    // normal truncated at 255, mu - sigma lambda(z), z = (255 - mu) / sigma, lambda = phi / Phi (the
    // inverse Mills ratio), with slope g = d/dmu = 1 - lambda (z + lambda) in (0, 1].
    const double z = (255.0 - mu) / clip_noise_grey;
    if (z < kClipNoiseNegligibleZ) {
      const double Phi = 0.5 * std::erfc(-z / std::numbers::sqrt2);
      const double phi = std::exp(-0.5 * z * z) * (0.5 * std::numbers::inv_sqrtpi * std::numbers::sqrt2);
      const double lambda = Phi > 1e-300 ? phi / Phi : -z;  // -z: its limit far above full scale
      const double g = std::max(1.0 - lambda * (z + lambda), 1e-6);
      p.s += clip_noise_grey * lambda;
      p.slope *= g;
      p.h *= g;
    }
  }
  return p;
}

}  // namespace

Eigen::Vector3d vignette_from_monotone(const Eigen::Vector3d& q, Eigen::Matrix3d* dv_dq) {
  const double a = q[0], b = q[1], c = q[2];
  if (dv_dq != nullptr) {
    *dv_dq << -2.0 * a, 0.0, 0.0,
              -b, -a, -c,
              0.0, -2.0 * b / 3.0, 2.0 * c / 3.0;
  }
  return {-a * a, -(2.0 * a * b + c * c) / 2.0, (c * c - b * b) / 3.0};
}

Eigen::Vector3d monotone_from_vignette(const Eigen::Vector3d& v, double floor) {
  const auto floored = [floor](Eigen::Vector3d q) {
    if (std::abs(q[0]) < floor) q[0] = q[0] < 0.0 ? -floor : floor;
    if (std::abs(q[2]) < floor) q[2] = q[2] < 0.0 ? -floor : floor;
    return q;
  };
  // Exact: a = sqrt(-v1), then b from b^2 + 2ab + 2 v2 + 3 v3 = 0 (eliminating c^2 between the
  // v2 and v3 equations), c^2 = -2 v2 - 2ab; the root with the larger c^2 wins.
  const double a = std::sqrt(std::max(-v[0], 0.0));
  const double discriminant = a * a - 2.0 * v[1] - 3.0 * v[2];
  std::optional<Eigen::Vector3d> best;
  double best_c2 = -1e-12;
  if (v[0] <= 0.0 && discriminant >= 0.0) {
    for (const double sign : {-1.0, 1.0}) {
      const double b = -a + sign * std::sqrt(discriminant);
      const double c2 = -2.0 * v[1] - 2.0 * a * b;
      if (c2 >= best_c2) {
        best_c2 = c2;
        best = Eigen::Vector3d(a, b, std::sqrt(std::max(c2, 0.0)));
      }
    }
  }
  if (best) return floored(*best);
  // Not a non-increasing V: the nearest v(q) in least squares, by Gauss-Newton.
  Eigen::Vector3d q(std::max(a, 0.3), 0.0, 0.3);
  for (int iteration = 0; iteration < 50; ++iteration) {
    Eigen::Matrix3d J;
    const Eigen::Vector3d r = vignette_from_monotone(q, &J) - v;
    const Eigen::Matrix3d A = J.transpose() * J + 1e-6 * Eigen::Matrix3d::Identity();
    const Eigen::Vector3d dq = A.ldlt().solve(-J.transpose() * r);
    if (!dq.allFinite()) break;
    q += dq;
    if (dq.norm() < 1e-10) break;
  }
  return floored(q);
}

InverseResponse::InverseResponse(const Eigen::Vector4d& c)
    : c_(c), table_(kInverseTableSize), du_dy_(kInverseTableSize) {
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
    double u = (j + t) / kGrid;
    // The nodes exact (Newton from the grid's chord), with their slopes du/dy = 1 / f'(u): the
    // cubic Hermite interpolant between them is within about 1e-13 of f^-1 where f' is away from
    // 0, so one Newton step per lookup reaches rounding where linear interpolation (1e-7) needed
    // two.
    double slope = 0.0;
    for (int iteration = 0; iteration < 3; ++iteration) {
      const double f = f_of_u(c_, u, &slope);
      if (!(slope > 1e-9)) break;
      u = std::clamp(u - (f - y) / slope, 0.0, 1.0);
    }
    f_of_u(c_, u, &slope);
    table_[static_cast<std::size_t>(i)] = u;
    du_dy_[static_cast<std::size_t>(i)] = slope > 1e-9 ? 1.0 / slope : 0.0;
  }
}

double InverseResponse::sqrt_irradiance(double y) const {
  y = std::clamp(y, 0.0, 1.0);
  constexpr double kSpacing = 1.0 / (kInverseTableSize - 1);
  const double position = y * (kInverseTableSize - 1);
  const int i = std::min(static_cast<int>(position), kInverseTableSize - 2);
  const double t = position - i;
  const auto k = static_cast<std::size_t>(i);
  // Cubic Hermite basis on [node i, node i + 1].
  const double t2 = t * t, t3 = t2 * t;
  double u = (2.0 * t3 - 3.0 * t2 + 1.0) * table_[k] + (t3 - 2.0 * t2 + t) * kSpacing * du_dy_[k] +
             (3.0 * t2 - 2.0 * t3) * table_[k + 1] + (t3 - t2) * kSpacing * du_dy_[k + 1];
  u = std::clamp(u, 0.0, 1.0);
  // One Newton step where the interpolant is good (everywhere but beside a zero slope, e.g. the
  // first cell of f(u) = u^2, where u = sqrt(y) is not smooth): after a step below 1e-7 the error
  // left is of order 1e-14.
  for (int iteration = 0; iteration < 8; ++iteration) {
    double slope = 0.0;
    const double f = f_of_u(c_, u, &slope);
    if (!(slope > 1e-9)) break;
    const double step = (f - y) / slope;
    u = std::clamp(u - step, 0.0, 1.0);
    if (std::abs(step) < 1e-7) break;
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

double predicted_grey_residual(const Eigen::Vector4d& c, const Eigen::Vector3d& v, double exposure, double radiance,
                               double grey, double radius, double illumination, PhotometricJacobian* jacobian,
                               double clip_noise_grey) {
  const double r2 = radius * radius;
  const double V = 1.0 + r2 * (v[0] + r2 * (v[1] + r2 * v[2]));
  const double eVa = exposure * V * illumination;
  const GreyPrediction p = predict_grey(c, eVa * radiance, grey, clip_noise_grey);
  if (jacobian != nullptr) {
    const double k = p.slope / (2.0 * p.u);  // dI/dG at the prediction
    jacobian->head<4>() = -255.0 * p.h;
    const double dV = -k * exposure * illumination * radiance;
    (*jacobian)[4] = dV * r2;
    (*jacobian)[5] = dV * r2 * r2;
    (*jacobian)[6] = dV * r2 * r2 * r2;
    (*jacobian)[7] = -k * V * illumination * radiance;
    (*jacobian)[8] = -k * eVa;
  }
  return p.s;
}

double ambient_grey_residual(const Eigen::Vector4d& c, const Eigen::Vector3d& v, double exposure, double radiance,
                             double kappa, double ambient_weight, double grey, double radius, double illumination,
                             AmbientJacobian* jacobian, double clip_noise_grey) {
  const double r2 = radius * radius;
  const double V = 1.0 + r2 * (v[0] + r2 * (v[1] + r2 * v[2]));
  const double lit = V * illumination + kappa * ambient_weight;
  const GreyPrediction p = predict_grey(c, exposure * lit * radiance, grey, clip_noise_grey);
  if (jacobian != nullptr) {
    const double k = p.slope / (2.0 * p.u);
    jacobian->head<4>() = -255.0 * p.h;
    const double dV = -k * exposure * illumination * radiance;
    (*jacobian)[4] = dV * r2;
    (*jacobian)[5] = dV * r2 * r2;
    (*jacobian)[6] = dV * r2 * r2 * r2;
    (*jacobian)[7] = -k * lit * radiance;
    (*jacobian)[8] = -k * exposure * lit;
    (*jacobian)[9] = -k * exposure * radiance * ambient_weight;
  }
  return p.s;
}

double lit_photometric_residual(const InverseResponse& inverse, const Eigen::Vector3d& v, double exposure,
                                double radiance, double grey, double radius, double illumination,
                                PhotometricJacobian* jacobian, double* d_residual_d_log_illumination) {
  // G / (e V a) - L is the plain residual at exposure e a; only dr/de picks up the factor a.
  const double r = photometric_residual(inverse, v, exposure * illumination, radiance, grey, radius, jacobian);
  if (jacobian != nullptr) (*jacobian)[7] *= illumination;
  if (d_residual_d_log_illumination != nullptr) *d_residual_d_log_illumination = -(r + radiance);
  return r;
}

double clip_bound_residual(const InverseResponse& inverse, const Eigen::Vector3d& v, double exposure, double radiance,
                           double clip_grey, double radius, double illumination, bool saturated,
                           PhotometricJacobian* jacobian) {
  const double r = lit_photometric_residual(inverse, v, exposure, radiance, clip_grey, radius, illumination, jacobian);
  const bool violated = saturated ? r > 0.0 : r < 0.0;
  if (violated) return r;
  if (jacobian != nullptr) jacobian->setZero();
  return 0.0;
}

PhotometricBackend::PhotometricBackend(PhotometricBackendOptions options)
    : options_(std::move(options)), response_(options_.initial_response), vignette_(options_.initial_vignette) {
  if (!response_.is_monotonic()) throw std::invalid_argument("photometric back end: the initial response is not monotonic");
  if (options_.max_keyframes < 2 || options_.max_stored_keyframes < options_.max_keyframes || options_.max_points < 1)
    throw std::invalid_argument("photometric back end: bad window options");
  if (options_.beam_halo) {
    beam_exponent_ = options_.beam_halo->initial_exponent();
    vignette_.v = options_.beam_halo->vignette(beam_exponent_);
  }
}

void PhotometricBackend::reset() {
  response_ = options_.initial_response;
  vignette_ = options_.initial_vignette;
  keyframes_.clear();
  added_ = 0;
  updates_since_multi_start_ = 0;
  response_fitted_ = false;
  response_fitted_unlit_ = false;
  ambient_ratio_ = 0.0;
  if (options_.beam_halo) {
    beam_exponent_ = options_.beam_halo->initial_exponent();
    vignette_.v = options_.beam_halo->vignette(beam_exponent_);
  }
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

std::size_t PhotometricBackend::fill_unknown_illumination(std::int64_t frame_index,
                                                         std::span<const TrackIllumination> values) {
  const auto keyframe = std::find_if(keyframes_.rbegin(), keyframes_.rend(),
                                     [&](const PhotometricKeyframe& k) { return k.frame_index == frame_index; });
  if (keyframe == keyframes_.rend() || !keyframe->illumination_modelled) return 0;
  std::unordered_map<std::int64_t, double> by_track;
  by_track.reserve(values.size());
  for (const TrackIllumination& value : values)
    if (std::isfinite(value.log_illumination)) by_track.emplace(value.track_id, value.log_illumination);
  std::size_t filled = 0;
  for (KeyframeObservation& o : keyframe->observations) {
    if (std::isfinite(o.log_illumination)) continue;
    if (const auto value = by_track.find(o.track_id); value != by_track.end()) {
      o.log_illumination = static_cast<float>(value->second);
      ++filled;
    }
  }
  return filled;
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
  // (track id, surface) -> (window position, observation) over the window: a track's observations
  // of different surfaces (keyframe_selection.hpp; only when the grid follows the surface) are
  // not of the same surface points.
  struct SurfaceKey {
    std::int64_t track_id;
    std::int32_t surface;
    bool operator==(const SurfaceKey&) const = default;
  };
  struct SurfaceHash {
    std::size_t operator()(const SurfaceKey& key) const {
      return std::hash<std::int64_t>()(key.track_id * 1000003 + key.surface);
    }
  };
  std::unordered_map<SurfaceKey, std::vector<std::pair<int, const KeyframeObservation*>>, SurfaceHash> tracks;
  for (int w = 0; w < static_cast<int>(window.size()); ++w)
    for (const KeyframeObservation& o : keyframes_[static_cast<std::size_t>(window[static_cast<std::size_t>(w)])].observations)
      tracks[SurfaceKey{o.track_id, o.surface}].emplace_back(w, &o);
  // A track's length: its observations with some normal sample (those with clipped samples only
  // add one-sided constraints, see the header).
  const auto normal_length = [](const std::vector<std::pair<int, const KeyframeObservation*>>& list) {
    std::size_t n = 0;
    for (const auto& [w, o] : list)
      n += std::any_of(o->grey.begin(), o->grey.end(), [](float g) { return g >= 0.0f; });
    return n;
  };
  std::vector<std::pair<std::size_t, const std::vector<std::pair<int, const KeyframeObservation*>>*>> usable;
  usable.reserve(tracks.size());
  for (const auto& [id, list] : tracks)
    if (const std::size_t n = normal_length(list); static_cast<int>(n) >= options_.min_observations_per_point)
      usable.emplace_back(n, &list);
  // Longest tracks first (most constraints per unknown); ties by track and surface for determinism.
  std::sort(usable.begin(), usable.end(), [](const auto& la, const auto& lb) {
    if (la.first != lb.first) return la.first > lb.first;
    const auto* a = la.second;
    const auto* b = lb.second;
    const KeyframeObservation& first_a = *(*a)[0].second;
    const KeyframeObservation& first_b = *(*b)[0].second;
    if (first_a.track_id != first_b.track_id) return first_a.track_id < first_b.track_id;
    return first_a.surface < first_b.surface;
  });
  // Once some keyframe of the window carries the light's factor, keyframes without it (before the
  // caller had distances) cannot be compared with them: their observations are left out.
  bool modelled = false;
  for (const int k : window) modelled |= keyframes_[static_cast<std::size_t>(k)].illumination_modelled;
  lit_problem_ = modelled;
  ambient_ = modelled && options_.lit_ambient;
  std::vector<double> log_references;  // per point (ambient_)
  const double mu = modelled ? options_.lit_gradient_mu : options_.gradient_mu;
  int track = 0;
  for (const auto& [length, list] : usable) {
    if (static_cast<int>(points_.size()) + kBackendPixels > options_.max_points) break;
    ++track;
    for (int k = 0; k < kBackendPixels; ++k) {
      Point point;
      point.begin = static_cast<int>(observations_.size());
      point.track = track;
      double log_reference = std::nan("");  // log a of the point's first normal observation
      // Normal samples first (the reference of the light's factor is among them), then the
      // clipped ones as bounds.
      int normal = 0;
      for (const int pass : {0, 1}) {
        for (const auto& [w, o] : *list) {
          const float grey = o->grey[static_cast<std::size_t>(k)];
          int bound = 0;
          if (grey == kGreySaturated && options_.saturation_bounds)
            bound = 1;
          else if (grey == kGreyDark && options_.black_bounds)
            bound = -1;
          else if (grey < 0.0f)
            continue;  // clipped (no bound asked for) or not sampled
          if ((bound != 0) != (pass == 1)) continue;
          if (pass == 1 && normal < options_.min_observations_per_point) break;  // L unknown: no bounds
          if (!std::isfinite(o->log_illumination)) continue;  // distance unknown
          if (modelled && !keyframes_[static_cast<std::size_t>(window[static_cast<std::size_t>(w)])].illumination_modelled) continue;
          if (std::isnan(log_reference)) log_reference = o->log_illumination;
          const PhotometricKeyframe& kf = keyframes_[static_cast<std::size_t>(window[static_cast<std::size_t>(w)])];
          // A bound at full scale itself, where G(255) = 255 ties the irradiance scale, takes no margin
          // (measured: clip_noise_grey in the header).
          const double saturation_margin =
              kf.saturation_grey >= 255.0 * kFullScaleSaturationLevel - 1e-3 ? 0.0 : options_.clip_bound_margin_grey;
          const Eigen::Vector2d p = o->pixel(k);
          Observation ob;
          ob.keyframe = w;
          ob.grey = bound > 0   ? static_cast<double>(kf.saturation_grey) - saturation_margin
                    : bound < 0 ? static_cast<double>(kf.black_grey) + options_.clip_bound_margin_grey
                                : static_cast<double>(grey);
          ob.bound = bound;
          ob.radius = VignetteModel::radius(p.x(), p.y(), kf.width, kf.height);
          if (options_.beam_halo && options_.beam_halo_exact) {
            ob.lens = options_.beam_halo->lens()(ob.radius);
            ob.log_cos = options_.beam_halo->log_cos(ob.radius);
          }
          ob.gradient_weight = mu / (mu + static_cast<double>(o->gradient_sq[static_cast<std::size_t>(k)]));
          ob.illumination = std::exp(static_cast<double>(o->log_illumination) - log_reference);
          observations_.push_back(ob);
          normal += bound == 0;
        }
      }
      point.end = static_cast<int>(observations_.size());
      if (normal >= options_.min_observations_per_point) {
        points_.push_back(point);
        if (ambient_) log_references.push_back(log_reference);
      } else {
        observations_.resize(static_cast<std::size_t>(point.begin));
      }
    }
  }
  if (ambient_ && !points_.empty()) {
    // w = W / A_ref, A_ref relative to the window's median point (kappa's unit).
    std::vector<double> sorted = log_references;
    const double median_log = median_in_place(sorted);
    for (std::size_t pi = 0; pi < points_.size(); ++pi) {
      const double relative = std::exp(median_log - log_references[pi]);
      for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
        Observation& o = observations_[static_cast<std::size_t>(i)];
        o.ambient_weight = (options_.beam_halo ? options_.beam_halo->lens()(o.radius) : 1.0) * relative;
      }
    }
  }
}

double PhotometricBackend::halo_at(const State& state, const Observation& o) const {
  if (options_.beam_halo && options_.beam_halo_exact) return o.lens * std::exp(state.q[0] * o.log_cos);
  return vignette_at(state.v, o.radius);
}

double PhotometricBackend::lit_exposure(const State& state, const Observation& o) const {
  const double e = state.exposure[static_cast<std::size_t>(o.keyframe)];
  if (!ambient_) return e * halo_at(state, o) * o.illumination;
  return e * (halo_at(state, o) * o.illumination + state.ambient * o.ambient_weight);
}

const InverseResponse& PhotometricBackend::inverse_response(const Eigen::Vector4d& c) const {
  for (const std::optional<InverseResponse>& slot : inverse_cache_)
    if (slot && slot->coefficients() == c) return *slot;
  std::optional<InverseResponse>& slot = inverse_cache_[inverse_cache_next_];
  inverse_cache_next_ = (inverse_cache_next_ + 1) % inverse_cache_.size();
  slot.emplace(c);
  return *slot;
}

void PhotometricBackend::update_u(State& state) const {
  const InverseResponse& inverse = inverse_response(state.c);
  state.u.resize(observations_.size());
  for (std::size_t i = 0; i < observations_.size(); ++i) state.u[i] = inverse.sqrt_irradiance(observations_[i].grey / 255.0);
}

void PhotometricBackend::initialise_radiances(State& state) const {
  // The weighted least-squares radiance for fixed globals: with weight (eVk)^2 on G/(eV) - L,
  // L = sum(w k^2 eV G) / sum(w k^2 (eV)^2).
  state.radiance.resize(points_.size());
  for (std::size_t pi = 0; pi < points_.size(); ++pi) {
    const Point& p = points_[pi];
    double num = 0.0, den = 0.0;
    for (int i = p.begin; i < p.end; ++i) {
      const Observation& o = observations_[static_cast<std::size_t>(i)];
      if (o.bound != 0) continue;  // from the normal samples
      const double u = state.u[static_cast<std::size_t>(i)];
      const double slope = f_slope(state.c, u);
      const double k = slope / (2.0 * std::max(u, 1e-6));
      const double G = 255.0 * u * u;
      const double eV = lit_exposure(state, o);
      const double w = o.gradient_weight * model_noise_weight(u, slope);
      num += w * k * k * eV * G;
      den += w * k * k * eV * eV;
    }
    state.radiance[pi] = den > 0.0 ? num / den : 0.0;
  }
}

double PhotometricBackend::scaled_residual(const State& state, std::size_t point, std::size_t i, double& slope,
                                           double* u_at) const {
  const Observation& o = observations_[i];
  const double irradiance = lit_exposure(state, o) * state.radiance[point];
  if (predicts_grey()) {
    const GreyPrediction p = predict_grey(state.c, irradiance, o.grey, clip_noise(o));
    slope = p.slope;
    if (u_at != nullptr) *u_at = p.u;
    return p.s;
  }
  const double u = state.u[i];
  slope = f_slope(state.c, u);
  if (u_at != nullptr) *u_at = u;
  const double k = slope / (2.0 * std::max(u, 1e-6));
  return (255.0 * u * u - irradiance) * k;
}

std::vector<double> PhotometricBackend::point_rms_residuals(const State& state, std::vector<double>& abs_s) const {
  std::vector<double> point_rms(points_.size(), 0.0);
  abs_s.clear();
  abs_s.reserve(observations_.size());
  if (options_.rejection == PhotometricBackendOptions::Rejection::Point) {
    for (std::size_t pi = 0; pi < points_.size(); ++pi) {
      double squared = 0.0;
      int normal = 0;
      for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
        if (observations_[static_cast<std::size_t>(i)].bound != 0) continue;
        double slope = 0.0, u = 0.0;
        const double s = scaled_residual(state, pi, static_cast<std::size_t>(i), slope, &u) * std::sqrt(model_noise_weight(u, slope));
        abs_s.push_back(std::abs(s));
        squared += s * s;
        ++normal;
      }
      point_rms[pi] = normal > 0 ? std::sqrt(squared / normal) : 0.0;
    }
    return point_rms;
  }
  // Against its patch: per track, the residuals in log irradiance by keyframe, the keyframe's
  // median over the track's pixels taken off, and the rest carried back to grey levels.
  struct Sample {
    int keyframe;
    std::size_t point;
    double log_residual;  // s / (dI / d log X)
    double grey_per_log;
  };
  std::vector<Sample> samples;
  std::vector<double> group;
  std::vector<double> squared(points_.size(), 0.0);
  std::vector<int> count(points_.size(), 0);
  for (std::size_t first = 0; first < points_.size();) {
    const std::size_t last = track_end(points_, first);
    samples.clear();
    for (std::size_t pi = first; pi < last; ++pi)
      for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
        if (observations_[static_cast<std::size_t>(i)].bound != 0) continue;
        double slope = 0.0, u = 0.0;
        const double s = scaled_residual(state, pi, static_cast<std::size_t>(i), slope, &u);
        const double grey_per_log = 127.5 * u * slope;  // dI / d log X, X = u^2, I = 255 f(u)
        if (!(grey_per_log > 1e-6)) continue;
        samples.push_back({observations_[static_cast<std::size_t>(i)].keyframe, pi, s / grey_per_log, grey_per_log});
      }
    std::sort(samples.begin(), samples.end(), [](const Sample& a, const Sample& b) { return a.keyframe < b.keyframe; });
    for (std::size_t a = 0; a < samples.size();) {
      std::size_t b = a;
      group.clear();
      while (b < samples.size() && samples[b].keyframe == samples[a].keyframe) group.push_back(samples[b++].log_residual);
      // A median of fewer than three pixels is one of them.
      if (group.size() >= 3) {
        const double shared = median_in_place(group);
        for (std::size_t j = a; j < b; ++j) {
          const double s = (samples[j].log_residual - shared) * samples[j].grey_per_log;
          abs_s.push_back(std::abs(s));
          squared[samples[j].point] += s * s;
          ++count[samples[j].point];
        }
      }
      a = b;
    }
    first = last;
  }
  for (std::size_t pi = 0; pi < points_.size(); ++pi) point_rms[pi] = count[pi] > 0 ? std::sqrt(squared[pi] / count[pi]) : 0.0;
  return point_rms;
}

int PhotometricBackend::drop_inconsistent_points(State& state, double sigmas) {
  std::vector<double> abs_s;
  const std::vector<double> point_rms = point_rms_residuals(state, abs_s);
  if (abs_s.empty()) return 0;
  // The floor as for the Huber width: on noise-free data the median is 0 and every point would go.
  const double bound = sigmas * std::max(1.4826 * median_in_place(abs_s), 0.5);
  std::vector<char> drop(points_.size());
  for (std::size_t pi = 0; pi < points_.size(); ++pi) drop[pi] = point_rms[pi] > bound;
  if (options_.reject_whole_track)
    for (std::size_t first = 0; first < points_.size();) {
      const std::size_t last = track_end(points_, first);
      const bool inconsistent = std::any_of(drop.begin() + static_cast<std::ptrdiff_t>(first),
                                            drop.begin() + static_cast<std::ptrdiff_t>(last), [](char d) { return d != 0; });
      if (inconsistent) std::fill(drop.begin() + static_cast<std::ptrdiff_t>(first), drop.begin() + static_cast<std::ptrdiff_t>(last), 1);
      first = last;
    }
  const auto kept = static_cast<int>(std::count(drop.begin(), drop.end(), 0));
  const int dropped = static_cast<int>(points_.size()) - kept;
  if (dropped == 0 || kept < options_.min_points) return 0;
  std::vector<Point> points;
  std::vector<Observation> observations;
  std::vector<double> radiance, u;
  points.reserve(static_cast<std::size_t>(kept));
  radiance.reserve(static_cast<std::size_t>(kept));
  observations.reserve(observations_.size());
  u.reserve(observations_.size());
  for (std::size_t pi = 0; pi < points_.size(); ++pi) {
    if (drop[pi]) continue;
    Point p;
    p.begin = static_cast<int>(observations.size());
    p.track = points_[pi].track;
    for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
      observations.push_back(observations_[static_cast<std::size_t>(i)]);
      u.push_back(state.u[static_cast<std::size_t>(i)]);
    }
    p.end = static_cast<int>(observations.size());
    points.push_back(p);
    radiance.push_back(state.radiance[pi]);
  }
  points_ = std::move(points);
  observations_ = std::move(observations);
  state.radiance = std::move(radiance);
  state.u = std::move(u);
  return dropped;
}

double PhotometricBackend::model_noise_weight(double u, double slope) const {
  if (!lit_problem_ || !(model_sigma_log_ > 0.0)) return 1.0;
  const double grey_per_log_irradiance = 127.5 * u * slope;  // dI/d log X = X f'(X), I in grey levels
  const double ratio = grey_per_log_irradiance * model_sigma_log_ / model_noise_grey_;
  return model_noise_norm_ / (1.0 + ratio * ratio);
}

bool PhotometricBackend::estimate_model_noise(const State& state, double& sigma_log, double& noise_grey) const {
  struct Sample {
    double x, abs_s;  // (dI/d log X)^2, |s|
  };
  std::vector<Sample> samples;
  samples.reserve(observations_.size());
  for (std::size_t pi = 0; pi < points_.size(); ++pi)
    for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
      if (observations_[static_cast<std::size_t>(i)].bound != 0) continue;
      double slope = 0.0;
      const double s = scaled_residual(state, pi, static_cast<std::size_t>(i), slope);
      const double g = 127.5 * state.u[static_cast<std::size_t>(i)] * slope;
      samples.push_back({g * g, std::abs(s)});
    }
  constexpr int kBins = 8;
  if (samples.size() < 20 * kBins) return false;
  std::sort(samples.begin(), samples.end(), [](const Sample& a, const Sample& b) { return a.x < b.x; });
  // Robust variance per bin, then var = A + B x by least squares over the bins (A, B >= 0).
  Eigen::Matrix2d N = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  std::vector<double> abs_s;
  for (int bin = 0; bin < kBins; ++bin) {
    const std::size_t begin = samples.size() * static_cast<std::size_t>(bin) / kBins;
    const std::size_t end = samples.size() * static_cast<std::size_t>(bin + 1) / kBins;
    abs_s.clear();
    double x = 0.0;
    for (std::size_t i = begin; i < end; ++i) abs_s.push_back(samples[i].abs_s), x += samples[i].x;
    x /= static_cast<double>(end - begin);
    const double sd = 1.4826 * median_in_place(abs_s);
    const Eigen::Vector2d row(1.0, x);
    N += row * row.transpose();
    rhs += row * (sd * sd);
  }
  Eigen::Vector2d ab = N.ldlt().solve(rhs);
  if (!ab.allFinite()) return false;
  if (ab[1] <= 0.0) return false;  // no growth with dI/d log X: the image noise alone
  if (ab[0] < 0.25) {                // refit the slope with the noise at its floor (0.5 grey levels)
    ab[0] = 0.25;
    ab[1] = (rhs[1] - N(1, 0) * ab[0]) / N(1, 1);
    if (!(ab[1] > 0.0)) return false;
  }
  noise_grey = std::sqrt(ab[0]);
  sigma_log = std::sqrt(ab[1]);
  return true;
}

double PhotometricBackend::data_cost(const State& state, double delta) const {
  // Scaled residual s = (G - e V L) k (grey levels), k = dI/dG; exposures pre-divided by e_scale.
  double cost = 0.0;
  for (std::size_t pi = 0; pi < points_.size(); ++pi) {
    for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
      double slope = 0.0, u = 0.0;
      const Observation& o = observations_[static_cast<std::size_t>(i)];
      const double s = bounded(o, scaled_residual(state, pi, static_cast<std::size_t>(i), slope, &u)) *
                       std::sqrt(model_noise_weight(u, slope));
      cost += o.gradient_weight * twice_huber_loss(s, delta);
    }
  }
  return cost;
}

std::optional<Eigen::Vector4d> PhotometricBackend::data_driven_response(const std::vector<double>& exposure,
                                                                        const std::vector<bool>& known,
                                                                        const Eigen::Vector3d& v, double grey_low,
                                                                        double grey_high, const Eigen::Vector4d& start) const {
  // Debevec-Malik style: the log inverse response g(I) = log G(I) on the 256 grey levels
  // (linear interpolation between levels), from g(I) - log L_p = log(e V a) over the observations
  // in known-exposure keyframes, with a second-difference smoothness term; log L_p eliminated
  // point by point (Schur), g pinned at the middle of the observed range (the additive constant
  // it shares with the log L_p).
  constexpr int kLevels = 256;
  const double normal_samples = static_cast<double>(
      std::count_if(observations_.begin(), observations_.end(), [](const Observation& o) { return o.bound == 0; }));
  const double smoothness = 0.01 * normal_samples / kLevels;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(kLevels, kLevels);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(kLevels);
  std::unordered_map<int, double> row;  // one point's coupling of g with its log L
  int used_points = 0;
  for (const Point& p : points_) {
    row.clear();
    double h_ll = 0.0, b_l = 0.0;
    for (int i = p.begin; i < p.end; ++i) {
      const Observation& o = observations_[static_cast<std::size_t>(i)];
      if (o.bound != 0 || !known[static_cast<std::size_t>(o.keyframe)] || o.grey < grey_low || o.grey > grey_high) continue;
      const double target = std::log(exposure[static_cast<std::size_t>(o.keyframe)] * vignette_at(v, o.radius) * o.illumination);
      const int k = std::min(static_cast<int>(o.grey), kLevels - 2);
      const double t = o.grey - k;
      const double w = o.gradient_weight;
      // residual g(I) - l - target, g(I) = (1 - t) g_k + t g_k+1.
      const std::pair<int, double> terms[2] = {{k, 1.0 - t}, {k + 1, t}};
      for (const auto& [ka, wa] : terms) {
        for (const auto& [kb, wb] : terms) H(ka, kb) += w * wa * wb;
        b[ka] += w * wa * target;
        row[ka] -= w * wa;  // d/dl of the residual is -1
      }
      h_ll += w;
      b_l -= w * target;
    }
    if (h_ll <= 0.0) continue;
    ++used_points;
    for (const auto& [ka, va] : row) {
      b[ka] -= va * b_l / h_ll;
      for (const auto& [kb, vb] : row) H(ka, kb) -= va * vb / h_ll;
    }
  }
  if (used_points < options_.min_points) return std::nullopt;
  for (int k = 1; k + 1 < kLevels; ++k) {
    const int idx[3] = {k - 1, k, k + 1};
    const double c2[3] = {1.0, -2.0, 1.0};
    for (int a = 0; a < 3; ++a)
      for (int bb = 0; bb < 3; ++bb) H(idx[a], idx[bb]) += smoothness * c2[a] * c2[bb];
  }
  const int pin = std::clamp(static_cast<int>(0.5 * (grey_low + grey_high)), 1, kLevels - 2);
  H(pin, pin) += 1e6 * smoothness;
  const Eigen::VectorXd g = H.ldlt().solve(b);
  if (!g.allFinite()) return std::nullopt;

  // Fit the model: log G_c(k) = g_k + s over the observed levels, Gauss-Newton in (c, s), steps
  // halved until f stays monotonic.
  const int lo = std::max(1, static_cast<int>(std::ceil(grey_low))), hi = std::min(254, static_cast<int>(grey_high));
  if (hi - lo < 8) return std::nullopt;
  Eigen::Vector4d c = start;
  const auto log_G = [](const InverseResponse& inverse, int k) {
    const double u = std::max(inverse.sqrt_irradiance(k / 255.0), 1e-6);
    return std::log(u * u);
  };
  const auto fit_cost = [&](const Eigen::Vector4d& cc, double shift) {
    const InverseResponse inverse(cc);
    double sum = 0.0;
    for (int k = lo; k <= hi; ++k) {
      const double r = log_G(inverse, k) - g[k] - shift;
      sum += r * r;
    }
    return sum;
  };
  double shift = 0.0;
  {
    const InverseResponse inverse(c);
    for (int k = lo; k <= hi; ++k) shift += (log_G(inverse, k) - g[k]) / (hi - lo + 1);
  }
  double cost = fit_cost(c, shift);
  for (int iteration = 0; iteration < 30; ++iteration) {
    const InverseResponse inverse(c);
    Eigen::Matrix<double, 5, 5> A = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> rhs = Eigen::Matrix<double, 5, 1>::Zero();
    for (int k = lo; k <= hi; ++k) {
      const double u = std::max(inverse.sqrt_irradiance(k / 255.0), 1e-6);
      Eigen::Vector4d h, dh;
      response_basis_in_sqrt_irradiance(u, h, dh);
      Eigen::Matrix<double, 5, 1> J;
      J.head<4>() = (2.0 / u) * (-h / (1.0 + c.dot(dh)));  // d log(u^2) / dc
      J[4] = -1.0;
      const double r = std::log(u * u) - g[k] - shift;
      A.noalias() += J * J.transpose();
      rhs -= J * r;
    }
    A.diagonal() *= 1.0 + 1e-6;
    Eigen::Matrix<double, 5, 1> dx = A.ldlt().solve(rhs);
    bool accepted = false;
    for (int half = 0; half < 10 && !accepted; ++half, dx *= 0.5) {
      const Eigen::Vector4d trial = c + dx.head<4>();
      if (!monotonic_on_grid(trial)) continue;
      const double trial_cost = fit_cost(trial, shift + dx[4]);
      if (trial_cost < cost) {
        accepted = true;
        const double decrease = cost - trial_cost;
        c = trial;
        shift += dx[4];
        cost = trial_cost;
        if (decrease < 1e-10 * (1.0 + cost)) iteration = 30;
      }
    }
    if (!accepted) break;
  }
  if (!c.allFinite() || !monotonic_on_grid(c)) return std::nullopt;
  return c;
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
  step.lit = lit_problem_;
  step.points = static_cast<int>(points_.size());
  for (const Observation& o : observations_) (o.bound == 0 ? step.observations : step.clip_bounds) += 1;
  if (step.points < options_.min_points) {
    step.status = "too few points tracked over several keyframes (" + std::to_string(step.points) + " < " +
                  std::to_string(options_.min_points) + "); last estimate kept";
    return step;
  }
  {
    std::vector<double> greys;
    greys.reserve(observations_.size());
    for (const Observation& o : observations_)
      if (o.bound == 0) greys.push_back(o.grey);
    const auto lo = greys.begin() + static_cast<std::ptrdiff_t>(greys.size() / 100);
    const auto hi = greys.begin() + static_cast<std::ptrdiff_t>(greys.size() - 1 - greys.size() / 100);
    std::nth_element(greys.begin(), lo, greys.end());
    step.grey_low = *lo;
    std::nth_element(greys.begin(), hi, greys.end());
    step.grey_high = *hi;
    std::vector<double> radii;
    radii.reserve(observations_.size());
    for (const Observation& o : observations_) radii.push_back(o.radius);
    const auto top = radii.begin() + static_cast<std::ptrdiff_t>(radii.size() - 1 - radii.size() / 100);
    std::nth_element(radii.begin(), top, radii.end());
    step.radius_high = std::min(*top, 1.0);
  }

  // Exposures, divided by their median so the numbers stay near 1 whatever the unit; free or held.
  const int K = step.keyframes;
  const auto keyframe = [&](int w) -> const PhotometricKeyframe& {
    return keyframes_[static_cast<std::size_t>(window_[static_cast<std::size_t>(w)])];
  };
  std::vector<double> exposure(static_cast<std::size_t>(K));
  for (int w = 0; w < K; ++w) exposure[static_cast<std::size_t>(w)] = keyframe(w).exposure;
  std::vector<double> sorted = exposure;
  const double e_scale = median_in_place(sorted);
  const double e_min = *std::min_element(exposure.begin(), exposure.end());
  const double e_max = *std::max_element(exposure.begin(), exposure.end());
  for (double& e : exposure) e /= e_scale;
  std::vector<int> free_index(static_cast<std::size_t>(K), -1);
  int globals = 7;
  bool any_fixed = false;
  for (int w = 0; w < K; ++w) any_fixed |= options_.trust_known_exposures && keyframe(w).exposure_known;
  // kappa (options.lit_ambient) before the exposures.
  const int ambient_index = ambient_ ? globals++ : -1;
  for (int w = 0; w < K; ++w) {
    const bool known = options_.trust_known_exposures && keyframe(w).exposure_known;
    // Without any reported exposure, the oldest keyframe of the window is the gauge.
    if (known || (!any_fixed && w == 0)) continue;
    free_index[static_cast<std::size_t>(w)] = globals++;
  }

  // Observability: the response needs the same points under different exposures, the vignette
  // the same points at different radii.
  int exposure_varying = 0;
  const double varying_log = 0.5 * std::log(options_.min_exposure_ratio);
  for (double e : exposure) exposure_varying += std::abs(std::log(e)) >= varying_log;  // e is over the median here
  const double varying_fraction = static_cast<double>(exposure_varying) / K;
  step.response_estimated = options_.estimate_response && e_max / e_min >= options_.min_exposure_ratio &&
                            varying_fraction >= options_.min_exposure_varying_fraction;
  const bool held_from_unlit = lit_problem_ && options_.lit_holds_unlit_response && response_fitted_unlit_;
  if (held_from_unlit) step.response_estimated = false;
  {
    int moving = 0;
    for (const Point& p : points_) {
      double lo = 2.0, hi = -1.0;
      for (int i = p.begin; i < p.end; ++i) {
        if (observations_[static_cast<std::size_t>(i)].bound != 0) continue;
        lo = std::min(lo, observations_[static_cast<std::size_t>(i)].radius);
        hi = std::max(hi, observations_[static_cast<std::size_t>(i)].radius);
      }
      moving += hi - lo >= options_.min_radius_span;
    }
    step.vignette_estimated = options_.estimate_vignette && moving >= options_.min_points / 2;
  }
  std::string held;
  if (!step.response_estimated)
    held += !options_.estimate_response ? "response held (fixed)"
            : held_from_unlit ? "response held (as fitted before the lamp's factor)"
            : e_max / e_min < options_.min_exposure_ratio
                ? "response held (exposure varies too little: " + std::to_string(e_max / e_min).substr(0, 4) + "x)"
                : "response held (exposure varies on " + std::to_string(exposure_varying) + " of " +
                      std::to_string(K) + " keyframes)";
  if (!step.vignette_estimated)
    held += std::string(held.empty() ? "" : "; ") +
            (options_.estimate_vignette ? "vignette held (points move too little across the image)" : "vignette held (fixed)");
  if (!step.response_estimated && !step.vignette_estimated && globals == 7) {
    step.status = "nothing observable: " + held + "; last estimate kept";
    return step;
  }

  const Eigen::Vector4d c_prior = options_.initial_response.coefficients();
  const double nobs = static_cast<double>(step.observations);  // normal samples: the priors' scale as without bounds
  const double prior_weight = options_.coefficient_prior_weight * nobs;
  const double monotonic_weight = options_.monotonic_penalty_weight * nobs;
  const MonotonicGrid& grid = monotonic_grid();


  State state;
  state.c = response_.coefficients();
  state.v = vignette_.v;
  // Steps must stay plausible (see the header), so start from a plausible V: the initial one,
  // else no vignetting.
  // Beam steps (options.beam_halo): the vignette's unknown is the beam's exponent, q = (m, 0, 0).
  const bool beam_steps = step.vignette_estimated && options_.beam_halo.has_value();
  if (!beam_steps && step.vignette_estimated && options_.vignette_monotonic && !VignetteModel{state.v}.is_plausible())
    state.v = VignetteModel{options_.initial_vignette.v}.is_plausible() ? options_.initial_vignette.v
                                                                                     : Eigen::Vector3d::Zero();
  // Monotone steps (VignetteSteps): the LM works in q, v = vignette_from_monotone(q).
  const bool monotone_steps = !beam_steps && step.vignette_estimated && options_.vignette_monotonic &&
                              (lit_problem_ ? options_.lit_vignette_steps : options_.vignette_steps) == VignetteSteps::Monotone;
  if (monotone_steps) {
    state.q = monotone_from_vignette(state.v);
    state.v = vignette_from_monotone(state.q);
  }
  if (options_.beam_halo) {  // held or estimated, q holds m (State)
    state.q = Eigen::Vector3d(beam_exponent_, 0.0, 0.0);
    state.v = options_.beam_halo->vignette(beam_exponent_);
  }
  state.exposure = exposure;
  state.ambient = ambient_ratio_;
  update_u(state);
  model_noise_norm_ = 1.0;
  model_sigma_log_ = 0.0;
  model_noise_grey_ = options_.lit_image_noise_grey;
  initialise_radiances(state);
  if (lit_problem_ && !observations_.empty()) {
    const double sigma = options_.lit_log_illumination_sigma;
    if (sigma > 0.0) {
      model_sigma_log_ = sigma;
    } else if (sigma < 0.0) {  // estimated from the residuals
      double sigma_log = 0.0, noise_grey = 1.0;
      if (estimate_model_noise(state, sigma_log, noise_grey)) {
        model_sigma_log_ = sigma_log;
        model_noise_grey_ = noise_grey;
      }
    }
    if (model_sigma_log_ > 0.0) {
      double sum = 0.0;
      for (std::size_t i = 0; i < observations_.size(); ++i)
        if (observations_[i].bound == 0) sum += model_noise_weight(state.u[i], f_slope(state.c, state.u[i]));
      if (sum > 0.0) model_noise_norm_ = static_cast<double>(step.observations) / sum;
      initialise_radiances(state);
    }
  }

  // Huber width from the robust spread of the scaled residuals at the start.
  double delta = 1.0;
  {
    std::vector<double> abs_s;
    abs_s.reserve(observations_.size());
    for (std::size_t pi = 0; pi < points_.size(); ++pi)
      for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
        if (observations_[static_cast<std::size_t>(i)].bound != 0) continue;
        double slope = 0.0, u = 0.0;
        const double s = scaled_residual(state, pi, static_cast<std::size_t>(i), slope, &u);
        abs_s.push_back(std::abs(s) * std::sqrt(model_noise_weight(u, slope)));
      }
    delta = options_.huber_k * std::max(1.4826 * median_in_place(abs_s), 0.5);
  }
  // The gamma gauge (see the header): without any known exposure, X_gauge(c) is pulled to the
  // initial response's value (when its weight is set).
  const bool gamma_gauge = step.response_estimated && !any_fixed && options_.gamma_gauge_weight > 0.0;
  const double gauge_weight = options_.gamma_gauge_weight * nobs;
  const double gauge_y = std::clamp(options_.gamma_gauge_grey / 255.0, 0.01, 0.99);
  const double gauge_target = [&] {
    const double u = InverseResponse(c_prior).sqrt_irradiance(gauge_y);
    return u * u;
  }();
  // X_gauge(c) and dX_gauge/dc.
  const auto gauge = [&](const Eigen::Vector4d& c, Eigen::Vector4d* gradient) {
    const double u = inverse_response(c).sqrt_irradiance(gauge_y);
    if (gradient != nullptr) {
      Eigen::Vector4d h, dh;
      response_basis_in_sqrt_irradiance(u, h, dh);
      *gradient = (-2.0 * u / (1.0 + c.dot(dh))) * h;
    }
    return u * u;
  };
  // The curvature of log G over log I (see log_curvature_weight in the header): second
  // differences of log X(I) = 2 log u(I) at grey levels evenly spaced in log I from a little
  // below the observed range's top to 255, and their gradients in c
  // (d log X / dc = (2 / u) du/dc, du/dc = -h(u) / f'(u)).
  // With known exposures only: without them gamma is free as well, and the result says it is
  // pinned only by the basis and the prior (online_calibration.hpp).
  // Scaled by the part of the grey scale above the observed range: where the data reach up to
  // saturation they fix the scale themselves and the prior must not bend their curve.
  const double curvature_weight =
      any_fixed ? (lit_problem_ ? options_.lit_log_curvature_weight : options_.log_curvature_weight) * nobs * std::max(0.0, 255.0 - step.grey_high) / 255.0 : 0.0;
  constexpr int kCurvatureLevels = 31;
  // Only from a little below the top of the observed range on: inside it the data fix the shape
  // (and log G is curved there by nature: log X ~ log I near black for every curve).
  // Grey levels evenly spaced in log I (5 % apart, the top at 255): a straight log G over log I
  // is a constant gamma, which the linear and gamma-like curves are.
  const auto curvature_grey = [](int j) { return 255.0 * std::exp(-0.05 * (kCurvatureLevels - 1 - j)); };
  int curvature_first = 0;
  while (curvature_first < kCurvatureLevels - 3 && curvature_grey(curvature_first) < step.grey_high - options_.log_curvature_overlap_grey) ++curvature_first;
  const auto log_curvature = [&](const Eigen::Vector4d& c, Eigen::Matrix<double, kCurvatureLevels - 2, 1>& rho,
                                 Eigen::Matrix<double, kCurvatureLevels - 2, 4>* jacobian) {
    const InverseResponse& inverse = inverse_response(c);
    Eigen::Matrix<double, kCurvatureLevels, 1> log_x;
    Eigen::Matrix<double, kCurvatureLevels, 4> d_log_x;
    for (int j = 0; j < kCurvatureLevels; ++j) {
      const double u = std::max(inverse.sqrt_irradiance(curvature_grey(j) / 255.0), 1e-6);
      log_x[j] = 2.0 * std::log(u);
      if (jacobian != nullptr) {
        Eigen::Vector4d h, dh;
        response_basis_in_sqrt_irradiance(u, h, dh);
        d_log_x.row(j) = ((2.0 / u) * (-h / std::max(1.0 + c.dot(dh), 1e-9))).transpose();
      }
    }
    rho.setZero();
    if (jacobian != nullptr) jacobian->setZero();
    for (int m = curvature_first; m + 2 < kCurvatureLevels; ++m) {
      rho[m] = log_x[m + 2] - 2.0 * log_x[m + 1] + log_x[m];
      if (jacobian != nullptr) jacobian->row(m) = d_log_x.row(m + 2) - 2.0 * d_log_x.row(m + 1) + d_log_x.row(m);
    }
  };
  const auto regulariser = [&](const Eigen::Vector4d& c) {
    if (!step.response_estimated) return 0.0;
    double penalty = prior_weight * (c - c_prior).squaredNorm();
    if (curvature_weight > 0.0) {
      Eigen::Matrix<double, kCurvatureLevels - 2, 1> rho;
      log_curvature(c, rho, nullptr);
      penalty += curvature_weight * rho.squaredNorm();
    }
    if (gamma_gauge) {
      const double miss = gauge(c, nullptr) - gauge_target;
      penalty += gauge_weight * miss * miss;
    }
    for (const Eigen::Vector4d& dh : grid.dh) {
      const double shortfall = options_.monotonic_margin - (1.0 + c.dot(dh));
      if (shortfall > 0.0) penalty += monotonic_weight * shortfall * shortfall;
    }
    return penalty;
  };
  // The straightness of V beyond the observed radii (vignette_rim_curvature_weight, header):
  // rho_j = d^2 V / dt^2 at t_j = r_j^2, r_j from the 99th percentile of the radii to 1; linear in v.
  constexpr int kRimRadii = 8;
  double rim_weight = 0.0;
  Eigen::Matrix<double, kRimRadii, 3> rim_jacobian = Eigen::Matrix<double, kRimRadii, 3>::Zero();
  if (step.vignette_estimated && !monotone_steps && !beam_steps && options_.vignette_rim_curvature_weight > 0.0) {
    const double r_high = step.radius_high;
    rim_weight = options_.vignette_rim_curvature_weight * nobs * (1.0 - r_high);
    for (int j = 0; j < kRimRadii; ++j) {
      const double r = r_high + (1.0 - r_high) * j / (kRimRadii - 1.0);
      rim_jacobian.row(j) << 0.0, 2.0, 6.0 * r * r;
    }
  }
  const auto rim_penalty = [&](const Eigen::Vector3d& v) {
    return rim_weight > 0.0 ? rim_weight * (rim_jacobian * v).squaredNorm() : 0.0;
  };
  const auto vignette_acceptable = [&](const Eigen::Vector3d& v) {
    return vignette_positive(v) && (!options_.vignette_monotonic || VignetteModel{v}.is_plausible());
  };
  const auto total_cost = [&](const State& st) { return data_cost(st, delta) + regulariser(st.c) + rim_penalty(st.v); };
  state.cost = total_cost(state);
  if (!std::isfinite(state.cost)) {
    step.ok = false;
    step.status = "cost not finite at the start; last estimate kept";
    return step;
  }

  Eigen::MatrixXd H(globals, globals), S(globals, globals);
  Eigen::VectorXd b(globals), rhs(globals), dx(globals), dx_try(globals);
  std::vector<double> h_pp(points_.size()), b_p(points_.size());
  std::vector<Eigen::Matrix<double, 7, 1>> h_pg(points_.size());
  std::vector<double> h_pe(observations_.size());  // coupling of each observation's point with its exposure
  std::vector<double> h_pk(ambient_ ? points_.size() : 0);  // ... and with kappa (ambient_)
  std::vector<int> index;
  std::vector<double> value;
  State trial;
  int total_iterations = 0;

  const bool predicted = predicts_grey();
  // Levenberg-Marquardt from `st` for up to `iterations`; returns whether it converged.
  const auto run_lm = [&](State& st, int iterations) {
    double lambda = 1e-3;
    for (int iteration = 0; iteration < iterations; ++iteration) {
      H.setZero();
      b.setZero();
      // With monotone or beam steps the vignette unknowns are q: dr/dq = (dv/dq)^T dr/dv (with
      // beam steps only its first column, dv/dm, is not zero: q2 and q3 get no step).
      Eigen::Matrix3d dv_dq = Eigen::Matrix3d::Identity();
      if (monotone_steps) vignette_from_monotone(st.q, &dv_dq);
      if (beam_steps) {
        Eigen::Vector3d dv_dm;
        options_.beam_halo->vignette(st.q[0], &dv_dm);
        dv_dq.setZero();
        dv_dq.col(0) = dv_dm;
      }
      const Eigen::Matrix3d dv_dq_t = dv_dq.transpose();
      for (std::size_t pi = 0; pi < points_.size(); ++pi) {
        const Point& p = points_[pi];
        const double L = st.radiance[pi];
        double hpp = 0.0, bp = 0.0, hpk = 0.0;
        Eigen::Matrix<double, 7, 1> hpg = Eigen::Matrix<double, 7, 1>::Zero();
        for (int i = p.begin; i < p.end; ++i) {
          const Observation& o = observations_[static_cast<std::size_t>(i)];
          const double e = st.exposure[static_cast<std::size_t>(o.keyframe)];
          const double r2 = o.radius * o.radius;
          const double V = halo_at(st, o);
          // The light's factor a rides with e V; with ambient light e (V a + kappa w) multiplies L.
          const double eV = ambient_ ? e * (V * o.illumination + st.ambient * o.ambient_weight) : e * V * o.illumination;
          // Predicted at full scale or above: nothing moves the prediction there (predict_grey), so
          // the sample's cost is the same for every step that keeps it there.
          if (predicted && predicted_above_full_scale(eV * L)) {
            h_pe[static_cast<std::size_t>(i)] = 0.0;
            continue;
          }
          // Linearised at the observed irradiance G(I) or, in the predicted form, at e V a L; the
          // residual r in radiance units either way (s = r e V k), so that dr/dL = -1 and the
          // derivatives in v and e below hold for both (PhotometricResidualForm).
          GreyPrediction at;
          if (predicted) {
            at = predict_grey(st.c, eV * L, o.grey, clip_noise(o));
          } else {
            at.u = st.u[static_cast<std::size_t>(i)];
            Eigen::Vector4d dh;
            response_basis_in_sqrt_irradiance(at.u, at.h, dh);
            at.slope = 1.0 + st.c.dot(dh);
          }
          const double u = at.u, slope = at.slope;
          const Eigen::Vector4d& h = at.h;
          const double k = slope / (2.0 * std::max(u, 1e-6));
          const double eVk = eV * k;
          const double r = predicted ? at.s / eVk : 255.0 * u * u / eV - L;
          const double noise_weight = model_noise_weight(u, slope);
          const double s = r * eVk * std::sqrt(noise_weight);
          if (bounded(o, s) == 0.0 && o.bound != 0) {  // a clipped sample whose bound holds: no cost
            h_pe[static_cast<std::size_t>(i)] = 0.0;
            continue;
          }
          // A violated bound: the residual and derivatives of a normal sample at the clip level.
          const double w = o.gradient_weight * noise_weight * eVk * eVk * huber_weight(s, delta);
          Eigen::Matrix<double, 7, 1> jg;
          if (step.response_estimated)
            jg.head<4>() = (-255.0 * 2.0 * u / (slope * eV)) * h;
          else
            jg.head<4>().setZero();
          // dV and de: derivatives of the grey-domain residual s = (G - e V L) k that the cost
          // holds (k frozen per linearisation), in r units: ds/dV / (eVk) = -L / V, not dr/dV =
          // -G / (e V^2) of r = G / (eV) - L. The two agree only where G = e V L; with the observed
          // (noisy) G in the Jacobian, the fixed point of the iteration is not the cost's minimum
          // but biased by E[G (G - e V L)] = var(G): measured on room/log observations (every 3rd
          // frame, response held; test_photometric_diagnostics.cpp, variant A), V came out too weak.
          if (step.vignette_estimated) {
            // With ambient light only the lamp's part goes through V: -L a / (V a + kappa w).
            const double dV = ambient_ ? -L * o.illumination * e / eV : -L / V;
            if (beam_steps && options_.beam_halo_exact) {
              jg.tail<3>() = Eigen::Vector3d(dV * V * o.log_cos, 0.0, 0.0);  // dV/dm = V log cos(alpha)
            } else {
              jg[4] = dV * r2;
              jg[5] = dV * r2 * r2;
              jg[6] = dV * r2 * r2 * r2;
              if (monotone_steps || beam_steps) jg.tail<3>() = dv_dq_t * jg.tail<3>().eval();
            }
          } else {
            jg.tail<3>().setZero();
          }
          const double je = -L / e;
          H.topLeftCorner<7, 7>().noalias() += w * jg * jg.transpose();
          b.head<7>() += (w * r) * jg;
          const int fe = free_index[static_cast<std::size_t>(o.keyframe)];
          if (fe >= 0) {
            H.block<7, 1>(0, fe) += (w * je) * jg;
            H(fe, fe) += w * je * je;
            b[fe] += w * r * je;
          }
          if (ambient_) {  // dr/dkappa = -L w e / (e (V a + kappa w))
            const double jk = -L * o.ambient_weight * e / eV;
            const int kI = ambient_index;
            H(kI, kI) += w * jk * jk;
            H.block<7, 1>(0, kI) += (w * jk) * jg;
            if (fe >= 0) {
              H(fe, kI) += w * je * jk;
              H(kI, fe) += w * je * jk;
            }
            b[kI] += w * r * jk;
            hpk -= w * jk;
          }
          // dr/dL = -1.
          hpp += w;
          bp -= w * r;
          hpg -= w * jg;
          h_pe[static_cast<std::size_t>(i)] = fe >= 0 ? -w * je : 0.0;
        }
        h_pp[pi] = hpp;
        b_p[pi] = bp;
        h_pg[pi] = hpg;
        if (ambient_) h_pk[pi] = hpk;
      }
      for (int g = 7; g < globals; ++g) H.block(g, 0, 1, 7) = H.block(0, g, 7, 1).transpose();
      if (step.response_estimated) {
        H.topLeftCorner<4, 4>().diagonal().array() += prior_weight;
        b.head<4>() += prior_weight * (st.c - c_prior);
        if (curvature_weight > 0.0) {
          Eigen::Matrix<double, kCurvatureLevels - 2, 1> rho;
          Eigen::Matrix<double, kCurvatureLevels - 2, 4> J;
          log_curvature(st.c, rho, &J);
          H.topLeftCorner<4, 4>().noalias() += curvature_weight * J.transpose() * J;
          b.head<4>() += curvature_weight * J.transpose() * rho;
        }
        if (gamma_gauge) {
          Eigen::Vector4d dX;
          const double miss = gauge(st.c, &dX) - gauge_target;
          H.topLeftCorner<4, 4>().noalias() += gauge_weight * dX * dX.transpose();
          b.head<4>() += gauge_weight * miss * dX;
        }
        for (const Eigen::Vector4d& dh : grid.dh) {
          const double shortfall = options_.monotonic_margin - (1.0 + st.c.dot(dh));
          if (shortfall > -options_.monotonic_margin) {  // active or nearly: keep the model quadratic
            H.topLeftCorner<4, 4>().noalias() += monotonic_weight * dh * dh.transpose();
            if (shortfall > 0.0) b.head<4>() -= monotonic_weight * shortfall * dh;
          }
        }
      }

      if (rim_weight > 0.0) {
        H.block<3, 3>(4, 4).noalias() += rim_weight * rim_jacobian.transpose() * rim_jacobian;
        b.segment<3>(4) += rim_weight * rim_jacobian.transpose() * (rim_jacobian * st.v);
      }

      bool accepted = false;
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
          if (ambient_) {
            index.push_back(ambient_index);
            value.push_back(h_pk[pi]);
          }
          for (int i = p.begin; i < p.end; ++i) {
            const int fe = free_index[static_cast<std::size_t>(observations_[static_cast<std::size_t>(i)].keyframe)];
            if (fe >= 0) {
              index.push_back(fe);
              value.push_back(h_pe[static_cast<std::size_t>(i)]);
            }
          }
          for (std::size_t a = 0; a < index.size(); ++a) {
            const double va = value[a] / d;
            rhs[index[a]] += va * b_p[pi];
            for (std::size_t bb = 0; bb < index.size(); ++bb) S(index[a], index[bb]) -= va * value[bb];
          }
        }
        dx = S.ldlt().solve(rhs);
        if (!dx.allFinite()) {
          lambda *= 10.0;
          continue;
        }
        // Backtracking: an invalid step (f not monotonic, e <= 0) is halved first. The vignette part
        // is shortened on its own to the plausible side (bisection on its length): V often rests on
        // the boundary (flat at the rim), where rejecting whole steps would freeze c and e too.
        bool valid = false;
        dx_try = dx;
        // With monotone steps the step is in q and only V(1) > 0.05 can fail (bisected the same way).
        const auto stepped_v = [&](double t) -> Eigen::Vector3d {
          if (beam_steps) return options_.beam_halo->vignette(st.q[0] + t * dx_try[4]);
          return monotone_steps ? vignette_from_monotone(st.q + t * dx_try.segment<3>(4))
                                : Eigen::Vector3d(st.v + t * dx_try.segment<3>(4));
        };
        for (int half = 0; half < 5 && !valid; ++half, dx_try *= 0.5) {
          trial.c = st.c + dx_try.head<4>();
          if (step.vignette_estimated && !vignette_acceptable(stepped_v(1.0))) {
            double lo = 0.0, hi = 1.0;
            for (int bisection = 0; bisection < 12; ++bisection) {
              const double mid = 0.5 * (lo + hi);
              (vignette_acceptable(stepped_v(mid)) ? lo : hi) = mid;
            }
            dx_try.segment<3>(4) *= lo;
          }
          trial.q = st.q + (monotone_steps ? Eigen::Vector3d(dx_try.segment<3>(4))
                            : beam_steps   ? Eigen::Vector3d(dx_try[4], 0.0, 0.0)
                                           : Eigen::Vector3d::Zero());
          trial.v = stepped_v(1.0);
          trial.exposure.resize(st.exposure.size());
          valid = true;
          for (int w = 0; w < K; ++w) {
            const int fe = free_index[static_cast<std::size_t>(w)];
            trial.exposure[static_cast<std::size_t>(w)] = st.exposure[static_cast<std::size_t>(w)] + (fe >= 0 ? dx_try[fe] : 0.0);
            valid &= trial.exposure[static_cast<std::size_t>(w)] > 0.0;
          }
          // kappa >= 0: a step below is cut at 0 (the cost decides whether it is taken).
          if (ambient_) trial.ambient = std::max(0.0, st.ambient + dx_try[ambient_index]);
          valid = valid && (!step.response_estimated || monotonic_on_grid(trial.c)) &&
                  (!step.vignette_estimated || vignette_acceptable(trial.v));
          if (valid) break;
        }
        if (!valid) {
          lambda *= 4.0;
          continue;
        }
        trial.radiance.resize(points_.size());
        for (std::size_t pi = 0; pi < points_.size(); ++pi) {
          const Point& p = points_[pi];
          const double d = h_pp[pi] * (1.0 + lambda) + 1e-12;
          double coupling = h_pg[pi].dot(dx_try.head<7>());
          if (ambient_) coupling += h_pk[pi] * dx_try[ambient_index];
          for (int i = p.begin; i < p.end; ++i) {
            const int fe = free_index[static_cast<std::size_t>(observations_[static_cast<std::size_t>(i)].keyframe)];
            if (fe >= 0) coupling += h_pe[static_cast<std::size_t>(i)] * dx_try[fe];
          }
          trial.radiance[pi] = st.radiance[pi] - (b_p[pi] + coupling) / d;
        }
        if (step.response_estimated)
          update_u(trial);
        else
          trial.u = st.u;  // f held: u unchanged
        trial.cost = total_cost(trial);
        if (std::isfinite(trial.cost) && trial.cost < st.cost) {
          accepted = true;
          const double decrease = st.cost - trial.cost;
          std::swap(st, trial);
          lambda = std::max(lambda / 3.0, 1e-9);
          ++total_iterations;
          if (decrease < options_.convergence_relative * st.cost) return true;
        } else {
          lambda *= 4.0;
        }
      }
      if (!accepted) return true;  // no step lowers the cost any more
    }
    return false;
  };

  // Multi-start (see the header): probe a few starting responses, continue from the cheapest.
  int remaining = max_iterations;
  if (step.response_estimated && options_.multi_start &&
      (all_stored || !response_fitted_ || ++updates_since_multi_start_ >= options_.multi_start_every)) {
    updates_since_multi_start_ = 0;
    step.multi_started = true;
    std::vector<Eigen::Vector4d> starts{state.c, c_prior, Eigen::Vector4d(-1.0, 0.0, 0.0, 0.0), Eigen::Vector4d::Zero()};
    // With known exposures, a start fitted to the data directly (see data_driven_response).
    if (any_fixed && options_.data_driven_start) {
      std::vector<bool> known(static_cast<std::size_t>(K));
      for (int w = 0; w < K; ++w) known[static_cast<std::size_t>(w)] = free_index[static_cast<std::size_t>(w)] < 0;
      if (const auto fitted = data_driven_response(state.exposure, known, state.v, step.grey_low, step.grey_high, state.c))
        starts.push_back(*fitted);
    }
    const int probe = std::min(options_.multi_start_probe_iterations, max_iterations);
    State best = state;
    run_lm(best, probe);
    // Each start with the current vignette and (when V is estimated) the initial one.
    for (std::size_t s = 0; s < 2 * starts.size(); ++s) {
      const std::size_t si = s / 2;
      const bool initial_v = s % 2 == 1;
      if (s == 0 || (initial_v && (!step.vignette_estimated || (options_.initial_vignette.v - state.v).norm() < 1e-9)))
        continue;
      bool duplicate = false;
      for (std::size_t t = 0; t < si; ++t) duplicate |= (starts[si] - starts[t]).norm() < 1e-6;
      if (duplicate || !monotonic_on_grid(starts[si])) continue;
      State candidate;
      candidate.c = starts[si];
      candidate.v = initial_v ? options_.initial_vignette.v : state.v;
      if (monotone_steps) {
        candidate.q = monotone_from_vignette(candidate.v);
        candidate.v = vignette_from_monotone(candidate.q);
      }
      if (options_.beam_halo) {
        candidate.q = Eigen::Vector3d(beam_steps && initial_v ? options_.beam_halo->initial_exponent() : state.q[0], 0.0, 0.0);
        candidate.v = options_.beam_halo->vignette(candidate.q[0]);
      }
      candidate.exposure = state.exposure;
      candidate.ambient = state.ambient;
      update_u(candidate);
      initialise_radiances(candidate);
      candidate.cost = total_cost(candidate);
      if (!std::isfinite(candidate.cost)) continue;
      run_lm(candidate, probe);
      if (candidate.cost < best.cost) std::swap(best, candidate);
    }
    std::swap(state, best);
    remaining = std::max(0, max_iterations - probe);
  }
  step.converged = remaining == 0 ? false : run_lm(state, remaining);
  if (const double sigmas = lit_problem_ ? options_.lit_point_rejection_sigmas : options_.point_rejection_sigmas;
      sigmas > 0.0 && std::isfinite(state.cost)) {
    step.points_rejected = drop_inconsistent_points(state, sigmas);
    if (step.points_rejected > 0) {
      step.points = static_cast<int>(points_.size());
      state.cost = total_cost(state);
      step.converged = run_lm(state, std::max(remaining, 1));
    }
  }
  step.iterations = total_iterations;
  step.cost = state.cost / nobs;
  if (!state.c.allFinite() || !state.v.allFinite()) {
    step.ok = false;
    step.status = "optimisation diverged (not finite); last estimate kept";
    return step;
  }
  if (!ResponseModel(state.c).is_monotonic()) {
    // Monotonic at the 256 test points but not on the finer check the model's users apply (a
    // flat stretch): back off towards the last published response, which is monotonic.
    const Eigen::Vector4d previous = response_.coefficients();
    Eigen::Vector4d c = previous;
    for (double t = 0.5; t > 1e-3; t *= 0.5) {
      const Eigen::Vector4d trial_c = previous + t * (state.c - previous);
      if (ResponseModel(trial_c).is_monotonic()) {
        c = trial_c;
        break;
      }
    }
    state.c = c;
    update_u(state);
    initialise_radiances(state);
    state.cost = total_cost(state);
  }
  step.updated = total_iterations > 0;
  if (step.updated && step.response_estimated) {
    response_fitted_ = true;
    response_fitted_unlit_ |= !lit_problem_;
  }
  response_ = ResponseModel(state.c);
  vignette_.v = state.v;
  if (beam_steps) beam_exponent_ = state.q[0];
  if (ambient_) {
    ambient_ratio_ = state.ambient;
    step.ambient = state.ambient;
    std::vector<double> shares;
    shares.reserve(points_.size());
    for (const Point& p : points_) {
      const Observation& o = observations_[static_cast<std::size_t>(p.begin)];  // the reference (a = 1)
      shares.push_back(state.ambient * o.ambient_weight / (halo_at(state, o) + state.ambient * o.ambient_weight));
    }
    step.ambient_share = median_in_place(shares);
  }
  for (int w = 0; w < K; ++w)
    keyframes_[static_cast<std::size_t>(window_[static_cast<std::size_t>(w)])].exposure = state.exposure[static_cast<std::size_t>(w)] * e_scale;
  {
    double squared = 0.0;
    std::size_t inliers = 0;
    std::vector<double> violations;
    for (std::size_t pi = 0; pi < points_.size(); ++pi)
      for (int i = points_[pi].begin; i < points_[pi].end; ++i) {
        double slope = 0.0, u = 0.0;
        const double s = scaled_residual(state, pi, static_cast<std::size_t>(i), slope, &u);
        if (const Observation& o = observations_[static_cast<std::size_t>(i)]; o.bound != 0) {
          if (bounded(o, s) != 0.0) violations.push_back(std::abs(s));
          continue;
        }
        if (std::abs(s) * std::sqrt(model_noise_weight(u, slope)) <= delta) squared += s * s, ++inliers;
      }
    step.residual_rms = inliers ? std::sqrt(squared / static_cast<double>(inliers)) : 0.0;
    step.clip_bounds_violated = static_cast<int>(violations.size());
    step.clip_bound_violation = median_in_place(violations);
  }
  char text[200];
  std::snprintf(text, sizeof text, "%s after %d iterations%s (%d keyframes, %d points, residual %.2f grey levels, %s)",
                step.converged ? "converged" : "iterating", step.iterations, step.multi_started ? " (multi-start)" : "",
                step.keyframes, step.points, step.residual_rms, predicted ? "I - f(e V L)" : "G(I) / (e V) - L");
  step.status = text;
  if (step.clip_bounds > 0) {
    char bounds[120];
    std::snprintf(bounds, sizeof bounds, "; clip bounds %d, %d violated (median %.2f grey levels)", step.clip_bounds,
                  step.clip_bounds_violated, step.clip_bound_violation);
    step.status += bounds;
  }
  if (step.points_rejected > 0) step.status += "; " + std::to_string(step.points_rejected) + " inconsistent points left out";
  if (ambient_) {
    char ambient[100];
    std::snprintf(ambient, sizeof ambient, "; ambient light %.3f of the lamp's at the median point (%.0f %% of a point's light, median)",
                  step.ambient, 100.0 * step.ambient_share);
    step.status += ambient;
  }
  if (!held.empty()) step.status += "; " + held;
  return step;
}

}  // namespace nirslam
