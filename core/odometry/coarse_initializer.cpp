#include "nirslam/odometry/coarse_initializer.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <thread>

#include <Eigen/Cholesky>

#include "nirslam/odometry/photometric_residual.hpp"
#include "nirslam/odometry/pixel_selector.hpp"

namespace nirslam::odometry {
namespace {
double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}
}  // namespace

CoarseInitializer::CoarseInitializer(std::vector<LevelCamera> cameras, const InitializerOptions& options)
    : cameras_(std::move(cameras)), options_(options) {}

void CoarseInitializer::set_first(std::shared_ptr<const ImagePyramid> pyramid, double exposure) {
  geometric_.clear();  // the poses were of the frames after another first frame
  aligned_to_geometric_ = false;
  first_ = std::move(pyramid);
  first_exposure_ = exposure;
  PixelSelectorOptions selection;
  selection.wanted = options_.points;
  selection.min_gradient = options_.min_gradient;
  // Far enough from the border that the pattern stays inside on the coarser levels too.
  selection.border = 4 << std::min(3, static_cast<int>(cameras_.size()) - 1);
  points_.clear();
  for (const auto& px : select_pixels(first_->level(0), selection))
    points_.push_back({px.cast<double>(), 1.0, true});

  // Six nearest neighbours per point (a grid-free O(n^2) pass is fine for ~1500 points once).
  neighbours_.assign(points_.size(), {});
  for (std::size_t i = 0; i < points_.size(); ++i) {
    std::array<std::pair<double, int>, 6> best;
    best.fill({1e30, static_cast<int>(i)});
    for (std::size_t j = 0; j < points_.size(); ++j) {
      if (i == j) continue;
      const double d = (points_[i].pixel - points_[j].pixel).squaredNorm();
      if (d < best.back().first) {
        best.back() = {d, static_cast<int>(j)};
        std::sort(best.begin(), best.end());
      }
    }
    for (std::size_t k = 0; k < 6; ++k) neighbours_[i][k] = best[k].second;
  }
  neighbour_mean_.assign(points_.size(), 1.0);
  T_frame_first_ = SE3();
  a_ = 0.0;
  b_ = 0.0;
  snapped_ = false;
  hypotheses_.clear();
  timings_ = {};
  frames_ = 0;
  frames_since_snap_ = 0;
  state_ = points_.size() >= 50 ? InitializerState::Tracking : InitializerState::Failed;
}

void CoarseInitializer::update_neighbour_means() {
  for (std::size_t i = 0; i < points_.size(); ++i) {
    std::array<double, 6> values{};
    for (std::size_t k = 0; k < 6; ++k)
      values[k] = points_[static_cast<std::size_t>(neighbours_[i][k])].inverse_depth;
    std::nth_element(values.begin(), values.begin() + 3, values.end());
    neighbour_mean_[i] = values[3];  // the median: robust to one wrong neighbour
  }
}

namespace {

// One point's pattern residuals in one frame: the robust energy and, with `linearize`, its
// blocks of the normal equations (frame parameters xi, a, b; the point's inverse depth).
struct PointTerms {
  double energy = 0.0;
  Matrix8d H_ff;
  Vector8d b_f;
  Vector8d H_fp;
  double H_pp = 0.0;
  double b_p = 0.0;
};

// False when the pattern leaves the first image or the frame, or the point is behind it.
bool point_terms(const LevelCamera& cam, const PyramidLevel& first, const PyramidLevel& image,
                 const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double s, double b, const Eigen::Vector2d& base,
                 double rho, double k, bool linearize, PointTerms& out) {
  out.energy = 0.0;
  if (linearize) {
    out.H_ff.setZero();
    out.b_f.setZero();
    out.H_fp.setZero();
    out.H_pp = 0.0;
    out.b_p = 0.0;
  }
  for (int p = 0; p < kPatternSize; ++p) {
    const auto& o = kPattern[static_cast<std::size_t>(p)];
    const Eigen::Vector2d px = base + Eigen::Vector2d(o[0], o[1]);
    if (!cam.inside(px.x(), px.y(), 1.0)) return false;
    Warp w;
    if (!warp_pixel(cam, R, t, px, rho, w) || !cam.inside(w.pixel.x(), w.pixel.y(), 2.0)) return false;
    const float host = first.interpolate_intensity(static_cast<float>(px.x()), static_cast<float>(px.y()));
    const Eigen::Vector3f sample = image.interpolate(static_cast<float>(w.pixel.x()), static_cast<float>(w.pixel.y()));
    const double host_term = s * host;
    const double r = sample[0] - host_term - b;
    const double hw = huber_weight(r, k);
    out.energy += hw * r * r * (2.0 - hw);
    if (!linearize) continue;
    Matrix26d d_pose;
    Eigen::Vector2d d_rho;
    warp_jacobians(cam, w, t, d_pose, d_rho);
    const Eigen::Vector2d grad = sample.tail<2>().cast<double>();
    Vector8d J;
    J.head<6>() = (grad.transpose() * d_pose).transpose();
    J[6] = -host_term;
    J[7] = -1.0;
    const double J_rho = grad.dot(d_rho);
    out.H_ff.noalias() += (hw * J) * J.transpose();
    out.b_f += hw * r * J;
    out.H_fp += hw * J_rho * J;
    out.H_pp += hw * J_rho * J_rho;
    out.b_p += hw * J_rho * r;
  }
  return true;
}

}  // namespace

double CoarseInitializer::evaluate(int level, const ImagePyramid& frame, double exposure, const SE3& T, double a,
                                   double b, const std::vector<double>& rho, bool linearize) {
  const LevelCamera& cam = cameras_[static_cast<std::size_t>(level)];
  const PyramidLevel& first = first_->level(level);
  const PyramidLevel& image = frame.level(level);
  const Eigen::Matrix3d R = T.rotation_matrix();
  const Eigen::Vector3d t = T.translation();
  const double s = std::exp(a) * exposure / first_exposure_;
  const double scale = 1.0 / static_cast<double>(1 << level);
  const double k = options_.huber_threshold;
  const double cutoff = 4.0 * k * k * kPatternSize * 4.0;
  const auto n = points_.size();
  if (linearize) {
    H_ff_.setZero();
    b_f_.setZero();
    H_fp_.assign(n, Eigen::Matrix<double, 8, 1>::Zero());
    H_pp_.assign(n, 0.0);
    b_p_.assign(n, 0.0);
  }
  inliers_.assign(n, 0);
  double energy = 0.0;
  double data_energy = 0.0;
  int data_count = 0;
  PointTerms terms;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d base = (points_[i].pixel.array() + 0.5) * scale - 0.5;
    const bool ok = point_terms(cam, first, image, R, t, s, b, base, rho[i], k, linearize, terms);
    if (!ok || terms.energy > cutoff) {
      energy += cutoff;
      // Still regularised, so an occluded or out-of-view point follows its neighbours.
    } else {
      inliers_[i] = 1;
      energy += terms.energy;
      data_energy += terms.energy;
      data_count += kPatternSize;
      if (linearize) {
        H_ff_ += terms.H_ff;
        b_f_ += terms.b_f;
        H_fp_[i] = terms.H_fp;
        H_pp_[i] = terms.H_pp;
        b_p_[i] = terms.b_p;
      }
    }
    // Depth regulariser.
    const double target = snapped_ ? neighbour_mean_[i] : 1.0;
    const double weight = snapped_ ? options_.neighbour_weight : options_.depth_prior_weight;
    const double d = rho[i] - target;
    energy += weight * d * d;
    if (linearize) {
      H_pp_[i] += weight;
      b_p_[i] += weight * d;
    }
  }
  if (snapped_ && hold_direction_.squaredNorm() > 0.5) {
    // A held direction u of the camera centre c (first frame): t = -R c must stay along -R u.
    // The perpendicular part is penalised as the pre-snap translation prior penalises t (its
    // Jacobian in upsilon only, the rotation's effect on t ignored likewise).
    const Eigen::Vector3d v = -(R * hold_direction_);
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - v * v.transpose();
    const double w = options_.translation_prior_weight * static_cast<double>(n);
    const Eigen::Vector3d e_perp = P * t;
    energy += w * e_perp.squaredNorm();
    if (linearize) {
      H_ff_.topLeftCorner<3, 3>() += w * P;
      b_f_.head<3>() += w * e_perp;
    }
  }
  // Translation regulariser before snapping, and the affine priors.
  const double tw = snapped_ ? 0.0 : options_.translation_prior_weight * static_cast<double>(n);
  energy += tw * t.squaredNorm() + options_.affine_a_prior * a * a + options_.affine_b_prior * b * b;
  if (linearize) {
    // d t / d upsilon = I for a left perturbation of (R, t); the rotation moves t too, ignored
    // here: the prior only has to keep t small.
    H_ff_.topLeftCorner<3, 3>().diagonal().array() += tw;
    b_f_.head<3>() += tw * t;
    H_ff_(6, 6) += options_.affine_a_prior;
    H_ff_(7, 7) += options_.affine_b_prior;
    b_f_(6) += options_.affine_a_prior * a;
    b_f_(7) += options_.affine_b_prior * b;
  }
  rms_ = data_count > 0 ? std::sqrt(data_energy / data_count) : 1e9;
  return energy;
}

double CoarseInitializer::optimize_level(int level, const ImagePyramid& frame, double exposure, int iterations) {
  std::vector<double> rho(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i) rho[i] = points_[i].inverse_depth;
  double energy = evaluate(level, frame, exposure, T_frame_first_, a_, b_, rho, true);
  double lambda = 0.1;
  std::vector<double> rho_new(rho.size());
  for (int it = 0; it < iterations; ++it) {
    // Schur complement over the points (one inverse depth each).
    Eigen::Matrix<double, 8, 8> H = H_ff_;
    H.diagonal() *= 1.0 + lambda;
    Eigen::Matrix<double, 8, 1> g = b_f_;
    for (std::size_t i = 0; i < rho.size(); ++i) {
      const double h = H_pp_[i] * (1.0 + lambda) + 1e-9;
      H -= H_fp_[i] * H_fp_[i].transpose() / h;
      g -= H_fp_[i] * (b_p_[i] / h);
    }
    const Eigen::Matrix<double, 8, 1> dx = H.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    for (std::size_t i = 0; i < rho.size(); ++i) {
      const double h = H_pp_[i] * (1.0 + lambda) + 1e-9;
      rho_new[i] = std::clamp(rho[i] - (b_p_[i] + H_fp_[i].dot(dx)) / h, 1e-3, 50.0);
    }
    const SE3 T_new = SE3::exp(dx.head<6>()) * T_frame_first_;
    const double a_new = a_ + dx[6];
    const double b_new = b_ + dx[7];
    // Keep the linearisation of the accepted state only.
    const auto H_ff = H_ff_;
    const auto b_f = b_f_;
    const auto H_fp = H_fp_;
    const auto H_pp = H_pp_;
    const auto b_p = b_p_;
    const double energy_new = evaluate(level, frame, exposure, T_new, a_new, b_new, rho_new, true);
    if (energy_new < energy) {
      energy = energy_new;
      T_frame_first_ = T_new;
      a_ = a_new;
      b_ = b_new;
      rho = rho_new;
      lambda = std::max(lambda * 0.5, 1e-4);
      if (dx.norm() < 1e-6) break;
    } else {
      H_ff_ = H_ff;
      b_f_ = b_f;
      H_fp_ = H_fp;
      H_pp_ = H_pp;
      b_p_ = b_p;
      lambda *= 4.0;
      if (lambda > 1e4) break;
    }
  }
  for (std::size_t i = 0; i < points_.size(); ++i) points_[i].inverse_depth = rho[i];
  evaluate(level, frame, exposure, T_frame_first_, a_, b_, rho, false);
  for (std::size_t i = 0; i < points_.size(); ++i) points_[i].good = inliers_[i] != 0;
  return rms_;
}

double CoarseInitializer::inlier_fraction() const {
  if (points_.empty()) return 0.0;
  std::size_t good = 0;
  for (const auto& p : points_) good += p.good ? 1 : 0;
  return static_cast<double>(good) / static_cast<double>(points_.size());
}

void CoarseInitializer::optimize_levels(const ImagePyramid& frame, double exposure) {
  const int levels = std::min(frame.levels(), static_cast<int>(cameras_.size()));
  for (int l = levels - 1; l >= 0; --l) {
    if (snapped_) update_neighbour_means();
    optimize_level(l, frame, exposure, l == 0 ? 8 : 12);
  }
}

double CoarseInitializer::normalise_gauge() {
  double mean = 0.0;
  for (const auto& p : points_) mean += p.inverse_depth;
  mean /= static_cast<double>(std::max<std::size_t>(1, points_.size()));
  if (!snapped_ || mean <= 1e-6) return 1.0;
  for (auto& p : points_) p.inverse_depth /= mean;
  T_frame_first_ = SE3(T_frame_first_.unit_quaternion(), T_frame_first_.translation() * mean);
  return mean;
}

double CoarseInitializer::translational_parallax() const {
  const LevelCamera& cam = cameras_[0];
  double sum = 0.0;
  int n = 0;
  for (const auto& p : points_) {
    Warp w;
    if (!warp_pixel(cam, Eigen::Matrix3d::Identity(), T_frame_first_.translation(), p.pixel, p.inverse_depth, w))
      continue;
    sum += (w.pixel - p.pixel).squaredNorm();
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) * 640.0 / cam.width : 0.0;
}

void CoarseInitializer::load(const Hypothesis& h) {
  T_frame_first_ = h.T;
  a_ = h.a;
  b_ = h.b;
  points_ = h.points;
}

void CoarseInitializer::align_hypothesis_range(CoarseInitializer& worker, std::size_t begin, std::size_t end,
                                               const ImagePyramid& frame, double exposure) {
  for (std::size_t k = begin; k < end; ++k) {
    Hypothesis& h = hypotheses_[k];
    worker.load(h);
    worker.hold_direction_ = h.hold_direction;
    worker.optimize_levels(frame, exposure);
    worker.hold_direction_ = Eigen::Vector3d::Zero();
    worker.normalise_gauge();
    std::vector<double> rho(worker.points_.size());
    for (std::size_t i = 0; i < worker.points_.size(); ++i) rho[i] = worker.points_[i].inverse_depth;
    worker.update_neighbour_means();
    const Eigen::Vector3d hold_direction = h.hold_direction;
    h = worker.current_state();
    h.hold_direction = hold_direction;
    h.energy = worker.evaluate(0, frame, exposure, worker.T_frame_first_, worker.a_, worker.b_, rho, false);
  }
}

template <class Range>
void CoarseInitializer::for_hypotheses(Range range) {
  const std::size_t n = hypotheses_.size();
  if (options_.parallel_hypotheses && n > 1) {
    // The second half on another thread with its own copy (state and scratch; hypotheses_ is
    // only written per index, each index by one thread), the first half here.
    const std::size_t half = (n + 1) / 2;
    CoarseInitializer copy(cameras_, options_);
    copy.first_ = first_;
    copy.first_exposure_ = first_exposure_;
    copy.neighbours_ = neighbours_;
    copy.neighbour_mean_ = neighbour_mean_;
    copy.snapped_ = snapped_;
    std::thread worker([&] { range(copy, half, n); });
    range(*this, 0, half);
    worker.join();
  } else {
    range(*this, 0, n);
  }
}

std::size_t CoarseInitializer::best_hypothesis() const {
  // The pre-snap hypothesis (0) is kept unless another start explains the frame clearly better:
  // over a small baseline the energies of different structures are close.
  std::size_t best = 0;
  for (std::size_t k = 1; k < hypotheses_.size(); ++k) {
    if (hypotheses_[k].energy < (1.0 - options_.hypothesis_margin) * hypotheses_[0].energy &&
        (best == 0 || hypotheses_[k].energy < hypotheses_[best].energy))
      best = k;
  }
  return best;
}

void CoarseInitializer::align_hypotheses(const ImagePyramid& frame, double exposure) {
  const auto align_start = std::chrono::steady_clock::now();
  if (static_cast<std::size_t>(frames_) < geometric_.size() && hypotheses_.size() == 1) {
    // The geometric start's pose of this frame, its camera centre's direction held.
    const SE3& T = geometric_[static_cast<std::size_t>(frames_)];
    const Eigen::Vector3d c = -(T.rotation_matrix().transpose() * T.translation());
    if (c.norm() > 1e-9) {
      hypotheses_[0].T = T;
      hypotheses_[0].hold_direction = c.normalized();
      aligned_to_geometric_ = true;
    }
  }
  for_hypotheses([&](CoarseInitializer& worker, std::size_t begin, std::size_t end) {
    align_hypothesis_range(worker, begin, end, frame, exposure);
  });
  timings_.align_s += seconds_since(align_start);
  load(hypotheses_[best_hypothesis()]);
  std::vector<double> rho(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i) rho[i] = points_[i].inverse_depth;
  update_neighbour_means();
  evaluate(0, frame, exposure, T_frame_first_, a_, b_, rho, false);
  for (std::size_t i = 0; i < points_.size(); ++i) points_[i].good = inliers_[i] != 0;
}

InitializerState CoarseInitializer::add_frame(std::shared_ptr<const ImagePyramid> frame, double exposure) {
  if (state_ != InitializerState::Tracking) return state_;
  ++frames_;
  if (snapped_) {
    align_hypotheses(*frame, exposure);
  } else {
    const auto start = std::chrono::steady_clock::now();
    optimize_levels(*frame, exposure);
    timings_.pre_snap_s += seconds_since(start);
    parallax_ = translational_parallax();
    if (parallax_ > options_.min_parallax_px) {
      snapped_ = true;
      hypotheses_.assign(1, current_state());
      const bool geometric = static_cast<std::size_t>(frames_) + 1 < geometric_.size();
      if (options_.multi_start_at_snap && !geometric) {
        const Eigen::Vector3d t = T_frame_first_.translation();
        const Eigen::Quaterniond q = T_frame_first_.unit_quaternion();
        hypotheses_.push_back({SE3(Eigen::Quaterniond::Identity(), t), a_, b_, points_, 0.0, Eigen::Vector3d::Zero()});
        for (const double sign : {-1.0, 1.0})
          hypotheses_.push_back({SE3(q, sign * t.norm() * Eigen::Vector3d::UnitZ()), a_, b_, points_, 0.0, Eigen::Vector3d::Zero()});
      }
      // The depth-regularised alignment starts on the next frame (more baseline): aligned on the
      // snap frame itself, the depths of the pre-snap pose wander along the small-baseline
      // ambiguity (room 50 W: 4.6 % of the path instead of 0.7 %).
    }
  }
  parallax_ = translational_parallax();
  if (snapped_ && ++frames_since_snap_ > options_.frames_after_snap) state_ = InitializerState::Succeeded;
  return state_;
}

}  // namespace nirslam::odometry
