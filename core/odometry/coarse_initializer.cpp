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
    : cameras_(std::move(cameras)), options_(options),
      offset_free_(options.patch_offset_invariant && !options.plain_pre_snap) {}

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
  pending_.clear();
  kept_frames_.clear();
  kept_exposures_.clear();
  kept_indices_.clear();
  kept_hypothesis_ = 0;
  early_hand_over_ = false;
  timings_ = {};
  offset_free_ = options_.patch_offset_invariant && !options_.plain_pre_snap;
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
// With `patch_offset`, the residuals are those left after the best brightness offset of this
// point's patch: the pattern's residuals and Jacobians minus their means over the pattern. The
// co-located lamp brightens a surface by (d_first / d_frame)^2 and its beam darkens it towards
// the image rim, so each patch changes brightness by its own factor, which the frame's affine
// brightness cannot follow; on the room and tunnel starts that bias moved the energy's minimum
// 6-19 degrees away from the true translation direction (README, "Odometry benchmark"). A free
// gain per patch as well is degenerate: a warp that shrinks the patch to a flat target explains
// any host patch (the starts then flip backwards).
bool point_terms(const LevelCamera& cam, const PyramidLevel& first, const PyramidLevel& image,
                 const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double s, double b, const Eigen::Vector2d& base,
                 double rho, double k, bool linearize, bool patch_offset, PointTerms& out) {
  out.energy = 0.0;
  if (linearize) {
    out.H_ff.setZero();
    out.b_f.setZero();
    out.H_fp.setZero();
    out.H_pp = 0.0;
    out.b_p = 0.0;
  }
  Eigen::Matrix<double, kPatternSize, 1> r_all;
  Eigen::Matrix<double, kPatternSize, 9> J_all;  // xi (6), a, b, rho
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
    if (patch_offset) {
      r_all[p] = r;
    } else {
      const double hw = huber_weight(r, k);
      out.energy += hw * r * r * (2.0 - hw);
    }
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
    if (patch_offset) {
      J_all.row(p).head<8>() = J.transpose();
      J_all(p, 8) = J_rho;
      continue;
    }
    const double hw = huber_weight(r, k);
    out.H_ff.noalias() += (hw * J) * J.transpose();
    out.b_f += hw * r * J;
    out.H_fp += hw * J_rho * J;
    out.H_pp += hw * J_rho * J_rho;
    out.b_p += hw * J_rho * r;
  }
  if (!patch_offset) return true;
  const Eigen::Matrix<double, kPatternSize, 1> r_proj = r_all.array() - r_all.mean();
  Eigen::Matrix<double, kPatternSize, 9> J_proj;
  if (linearize) J_proj = J_all.rowwise() - J_all.colwise().mean();
  for (int p = 0; p < kPatternSize; ++p) {
    const double r = r_proj[p];
    const double hw = huber_weight(r, k);
    out.energy += hw * r * r * (2.0 - hw);
    if (!linearize) continue;
    const Vector8d J = J_proj.row(p).head<8>().transpose();
    const double J_rho = J_proj(p, 8);
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
  visible_energy_ = 0.0;
  visible_count_ = 0;
  double energy = 0.0;
  double data_energy = 0.0;
  int data_count = 0;
  PointTerms terms;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d base = (points_[i].pixel.array() + 0.5) * scale - 0.5;
    const bool ok = point_terms(cam, first, image, R, t, s, b, base, rho[i], k, linearize, offset_free_, terms);
    if (ok) {
      visible_energy_ += std::min(terms.energy, cutoff);
      ++visible_count_;
    }
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

double CoarseInitializer::evaluate_joint(int level, const std::vector<FrameState>& states,
                                         const std::vector<double>& rho, bool linearize) {
  const LevelCamera& cam = cameras_[static_cast<std::size_t>(level)];
  const PyramidLevel& first = first_->level(level);
  const double scale = 1.0 / static_cast<double>(1 << level);
  const double k = options_.huber_threshold;
  const double cutoff = 4.0 * k * k * kPatternSize * 4.0;
  const auto n = points_.size();
  const auto frames = states.size();
  const auto dim = static_cast<Eigen::Index>(8 * frames);
  if (linearize) {
    JH_ff_.setZero(dim, dim);
    Jb_f_.setZero(dim);
    JH_fp_.setZero(dim, static_cast<Eigen::Index>(n));
    H_pp_.assign(n, 0.0);
    b_p_.assign(n, 0.0);
  }
  inliers_.assign(n, 0);
  visible_energy_ = 0.0;
  visible_count_ = 0;
  std::vector<Eigen::Matrix3d> R(frames);
  std::vector<double> s(frames);
  for (std::size_t f = 0; f < frames; ++f) {
    R[f] = states[f].T.rotation_matrix();
    s[f] = std::exp(states[f].a) * kept_exposures_[f] / first_exposure_;
  }
  double energy = 0.0;
  double data_energy = 0.0;  // of the last frame, for rms_
  int data_count = 0;
  PointTerms terms;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d base = (points_[i].pixel.array() + 0.5) * scale - 0.5;
    for (std::size_t f = 0; f < frames; ++f) {
      const bool ok = point_terms(cam, first, kept_frames_[f]->level(level), R[f], states[f].T.translation(), s[f],
                                  states[f].b, base, rho[i], k, linearize, options_.patch_offset_invariant, terms);
      if (ok) {
        visible_energy_ += std::min(terms.energy, cutoff);
        ++visible_count_;
      }
      if (!ok || terms.energy > cutoff) {
        energy += cutoff;
        continue;
      }
      energy += terms.energy;
      if (f + 1 == frames) {
        inliers_[i] = 1;
        data_energy += terms.energy;
        data_count += kPatternSize;
      }
      if (linearize) {
        const auto o = static_cast<Eigen::Index>(8 * f);
        JH_ff_.block<8, 8>(o, o) += terms.H_ff;
        Jb_f_.segment<8>(o) += terms.b_f;
        JH_fp_.block<8, 1>(o, static_cast<Eigen::Index>(i)) = terms.H_fp;
        H_pp_[i] += terms.H_pp;
        b_p_[i] += terms.b_p;
      }
    }
    const double d = rho[i] - neighbour_mean_[i];
    energy += options_.neighbour_weight * d * d;
    if (linearize) {
      H_pp_[i] += options_.neighbour_weight;
      b_p_[i] += options_.neighbour_weight * d;
    }
  }
  for (std::size_t f = 0; f < frames; ++f) {
    const double a = states[f].a;
    const double b = states[f].b;
    energy += options_.affine_a_prior * a * a + options_.affine_b_prior * b * b;
    if (linearize) {
      const auto o = static_cast<Eigen::Index>(8 * f);
      JH_ff_(o + 6, o + 6) += options_.affine_a_prior;
      JH_ff_(o + 7, o + 7) += options_.affine_b_prior;
      Jb_f_(o + 6) += options_.affine_a_prior * a;
      Jb_f_(o + 7) += options_.affine_b_prior * b;
    }
  }
  rms_ = data_count > 0 ? std::sqrt(data_energy / data_count) : 1e9;
  return energy;
}

void CoarseInitializer::optimize_joint_level(int level, std::vector<FrameState>& states, int iterations) {
  const auto n = points_.size();
  std::vector<double> rho(n);
  for (std::size_t i = 0; i < n; ++i) rho[i] = points_[i].inverse_depth;
  double energy = evaluate_joint(level, states, rho, true);
  double lambda = 0.1;
  std::vector<double> rho_new(n);
  Eigen::VectorXd inv_h(static_cast<Eigen::Index>(n));
  for (int it = 0; it < iterations; ++it) {
    // Schur complement over the points: S = H_ff - H_fp diag(1 / h) H_fp^T.
    for (std::size_t i = 0; i < n; ++i) inv_h[static_cast<Eigen::Index>(i)] = 1.0 / (H_pp_[i] * (1.0 + lambda) + 1e-9);
    Eigen::MatrixXd S = JH_ff_;
    S.diagonal() *= 1.0 + lambda;
    const Eigen::MatrixXd W = JH_fp_ * inv_h.cwiseSqrt().asDiagonal();
    S.selfadjointView<Eigen::Lower>().rankUpdate(W, -1.0);
    S.triangularView<Eigen::StrictlyUpper>() = S.transpose();
    const Eigen::VectorXd b_p = Eigen::Map<const Eigen::VectorXd>(b_p_.data(), static_cast<Eigen::Index>(n));
    const Eigen::VectorXd g = Jb_f_ - JH_fp_ * inv_h.cwiseProduct(b_p);
    const Eigen::VectorXd dx = S.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    const Eigen::VectorXd coupling = JH_fp_.transpose() * dx;
    for (std::size_t i = 0; i < n; ++i) {
      const auto ii = static_cast<Eigen::Index>(i);
      rho_new[i] = std::clamp(rho[i] - (b_p_[i] + coupling[ii]) * inv_h[ii], 1e-3, 50.0);
    }
    std::vector<FrameState> states_new = states;
    for (std::size_t f = 0; f < states.size(); ++f) {
      const auto o = static_cast<Eigen::Index>(8 * f);
      states_new[f].T = SE3::exp(dx.segment<6>(o)) * states[f].T;
      states_new[f].a += dx[o + 6];
      states_new[f].b += dx[o + 7];
    }
    // Keep the linearisation of the accepted state only.
    Eigen::MatrixXd H_ff = JH_ff_;
    Eigen::VectorXd b_f = Jb_f_;
    Eigen::MatrixXd H_fp = JH_fp_;
    std::vector<double> H_pp = H_pp_;
    std::vector<double> b_p_old = b_p_;
    const double energy_new = evaluate_joint(level, states_new, rho_new, true);
    if (energy_new < energy) {
      energy = energy_new;
      states = std::move(states_new);
      rho = rho_new;
      lambda = std::max(lambda * 0.5, 1e-4);
      if (dx.norm() < 1e-6) break;
    } else {
      JH_ff_ = std::move(H_ff);
      Jb_f_ = std::move(b_f);
      JH_fp_ = std::move(H_fp);
      H_pp_ = std::move(H_pp);
      b_p_ = std::move(b_p_old);
      lambda *= 4.0;
      if (lambda > 1e4) break;
    }
  }
  for (std::size_t i = 0; i < n; ++i) points_[i].inverse_depth = rho[i];
}

void CoarseInitializer::sweep_depths(const std::vector<FrameState>& states, int level) {
  const LevelCamera& cam = cameras_[static_cast<std::size_t>(level)];
  const PyramidLevel& first = first_->level(level);
  const double scale = 1.0 / static_cast<double>(1 << level);
  const double k = options_.huber_threshold;
  const double cutoff = 4.0 * k * k * kPatternSize * 4.0;
  const auto frames = states.size();
  std::vector<Eigen::Matrix3d> R(frames);
  std::vector<double> s(frames);
  for (std::size_t f = 0; f < frames; ++f) {
    R[f] = states[f].T.rotation_matrix();
    s[f] = std::exp(states[f].a) * kept_exposures_[f] / first_exposure_;
  }
  const int steps = options_.depth_sweep_steps;
  const double rho_max = 4.0;
  PointTerms terms;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const Eigen::Vector2d base = (points_[i].pixel.array() + 0.5) * scale - 0.5;
    double best = 1e300;
    double best_rho = points_[i].inverse_depth;
    for (int j = 0; j < steps; ++j) {
      const double rho = rho_max * (j + 0.5) / steps;
      double e = 0.0;
      for (std::size_t f = 0; f < frames && e < best; ++f) {
        const bool ok = point_terms(cam, first, kept_frames_[f]->level(level), R[f], states[f].T.translation(), s[f],
                                    states[f].b, base, rho, k, false, options_.patch_offset_invariant, terms);
        e += ok ? std::min(terms.energy, cutoff) : cutoff;
      }
      if (e < best) {
        best = e;
        best_rho = rho;
      }
    }
    points_[i].inverse_depth = best_rho;
  }
}

void CoarseInitializer::refine_joint(Hypothesis& h) {
  load(h);
  std::vector<FrameState> states = h.track;
  if (options_.depth_sweep_steps > 0) {
    // The depths the hypothesis carries are fitted frame by frame and lag its poses; every depth
    // is searched again along its rays in all kept frames at once (no local minima along the
    // ray), so that hypotheses are compared on their motion, not on how far their depths got.
    sweep_depths(states, 0);
    double mean = 0.0;
    for (const auto& p : points_) mean += p.inverse_depth;
    mean /= static_cast<double>(std::max<std::size_t>(1, points_.size()));
    for (auto& p : points_) p.inverse_depth /= mean;
    for (auto& st : states) st.T = SE3(st.T.unit_quaternion(), st.T.translation() * mean);
  }
  const int levels = std::min(first_->levels(), static_cast<int>(cameras_.size()));
  for (int l = levels - 1; l >= 0; --l) {
    update_neighbour_means();
    optimize_joint_level(l, states, l == 0 ? 8 : 12);
    // Gauge: mean inverse depth 1, every translation scaled along.
    double mean = 0.0;
    for (const auto& p : points_) mean += p.inverse_depth;
    mean /= static_cast<double>(std::max<std::size_t>(1, points_.size()));
    if (mean > 1e-6) {
      for (auto& p : points_) p.inverse_depth /= mean;
      for (auto& st : states) st.T = SE3(st.T.unit_quaternion(), st.T.translation() * mean);
    }
  }
  update_neighbour_means();
  std::vector<double> rho(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i) rho[i] = points_[i].inverse_depth;
  const double energy = evaluate_joint(0, states, rho, false);
  for (std::size_t i = 0; i < points_.size(); ++i) points_[i].good = inliers_[i] != 0;
  h.points = points_;
  h.track = states;
  h.T = states.back().T;
  h.a = states.back().a;
  h.b = states.back().b;
  // Points leaving the view count as outliers in `energy`: a motion that keeps more points in
  // view would look better for that alone. The mean over the point-frames in view does not.
  h.energy = options_.select_by_mean_visible_energy ? visible_energy_ / std::max(1, visible_count_) : energy;
  h.rms = rms_;
  h.inlier_fraction = inlier_fraction();
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
    worker.offset_free_ = h.offset_free;
    worker.optimize_levels(frame, exposure);
    worker.hold_direction_ = Eigen::Vector3d::Zero();
    const double gauge = worker.normalise_gauge();
    std::vector<double> rho(worker.points_.size());
    for (std::size_t i = 0; i < worker.points_.size(); ++i) rho[i] = worker.points_[i].inverse_depth;
    worker.update_neighbour_means();
    auto track = std::move(h.track);
    const Eigen::Vector3d hold_direction = h.hold_direction;
    const bool search = h.search;
    h = worker.current_state();
    h.hold_direction = hold_direction;
    h.search = search;
    h.energy = worker.evaluate(0, frame, exposure, worker.T_frame_first_, worker.a_, worker.b_, rho, false);
    h.visible_mean = worker.visible_energy_ / std::max(1, worker.visible_count_);
    // The earlier frames' translations follow the gauge (the depths were scaled by 1 / gauge).
    for (auto& st : track) st.T = SE3(st.T.unit_quaternion(), st.T.translation() * gauge);
    track.push_back({h.T, h.a, h.b});
    h.track = std::move(track);
  }
}

void CoarseInitializer::refine_hypothesis_range(CoarseInitializer& worker, std::size_t begin, std::size_t end) {
  for (std::size_t k = begin; k < end; ++k) worker.refine_joint(hypotheses_[k]);
}

template <class Range>
void CoarseInitializer::for_hypotheses(Range range, std::size_t begin) {
  const std::size_t n = hypotheses_.size();
  if (options_.parallel_hypotheses && n > begin + 1) {
    // The second half on another thread with its own copy (state and scratch; hypotheses_ is
    // only written per index, each index by one thread), the first half here.
    const std::size_t half = begin + (n - begin + 1) / 2;
    CoarseInitializer copy(cameras_, options_);
    copy.first_ = first_;
    copy.first_exposure_ = first_exposure_;
    copy.neighbours_ = neighbours_;
    copy.neighbour_mean_ = neighbour_mean_;
    copy.snapped_ = snapped_;
    copy.kept_frames_ = kept_frames_;
    copy.kept_exposures_ = kept_exposures_;
    std::thread worker([&] { range(copy, half, n); });
    range(*this, begin, half);
    worker.join();
  } else {
    range(*this, begin, n);
  }
}

std::size_t CoarseInitializer::plain_choice() const {
  // The pre-snap hypothesis (0) is kept unless another start explains the frame clearly better:
  // over a small baseline the energies of different structures are close.
  std::size_t best = 0;
  for (std::size_t k = 1; k < hypotheses_.size(); ++k) {
    if (hypotheses_[k].search) continue;
    if (hypotheses_[k].energy < (1.0 - options_.hypothesis_margin) * hypotheses_[0].energy &&
        (best == 0 || hypotheses_[k].energy < hypotheses_[best].energy))
      best = k;
  }
  return best;
}

void CoarseInitializer::prune_candidates() {
  std::vector<std::size_t> candidates;
  for (std::size_t k = 0; k < hypotheses_.size(); ++k)
    if (hypotheses_[k].candidate()) candidates.push_back(k);
  const auto keep = static_cast<std::size_t>(std::max(0, options_.candidates_kept));
  if (candidates.size() <= keep) return;
  // Stable, so equal energies keep their cone order (the same on one thread or two).
  std::stable_sort(candidates.begin(), candidates.end(), [&](std::size_t x, std::size_t y) {
    return hypotheses_[x].visible_mean < hypotheses_[y].visible_mean;
  });
  std::vector<char> dropped(hypotheses_.size(), 0);
  for (std::size_t j = keep; j < candidates.size(); ++j) dropped[candidates[j]] = 1;
  std::vector<Hypothesis> kept;
  kept.reserve(hypotheses_.size() - (candidates.size() - keep));
  for (std::size_t k = 0; k < hypotheses_.size(); ++k)
    if (!dropped[k]) kept.push_back(std::move(hypotheses_[k]));
  hypotheses_ = std::move(kept);
}

bool CoarseInitializer::align_hypotheses(const ImagePyramid& frame, double exposure) {
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

  bool hand_over_now = false;
  std::size_t best = plain_choice();
  const bool search = options_.direction_rings > 0;
  const bool gate = search && options_.plain_hand_over_frames > 0;
  if (gate && frames_since_snap_ == options_.plain_hand_over_frames) {
    if (best != 0) {
      // Another start is clearly better than the pre-snap one (vehicle motion): the plain
      // path's result, now; the candidates were never aligned.
      hand_over_now = true;
      pending_.clear();
    } else {
      // The search goes on: the candidates catch up on the frames kept since the snap (the
      // same alignments as from the snap on, since each hypothesis is aligned on its own).
      const std::size_t first_candidate = hypotheses_.size();
      first_search_ = first_candidate;
      for (auto& h : pending_) hypotheses_.push_back(std::move(h));
      pending_.clear();
      for (std::size_t f = 0; f < kept_frames_.size(); ++f) {
        for_hypotheses(
            [&](CoarseInitializer& worker, std::size_t begin, std::size_t end) {
              align_hypothesis_range(worker, begin, end, *kept_frames_[f], kept_exposures_[f]);
            },
            first_candidate);
        if (options_.candidates_kept > 0 && static_cast<int>(f) + 1 == options_.prune_after_frames) prune_candidates();
      }
    }
  } else if (search && options_.candidates_kept > 0 && frames_since_snap_ == options_.prune_after_frames &&
             (!gate || options_.prune_after_frames > options_.plain_hand_over_frames)) {
    prune_candidates();
  }
  timings_.align_s += seconds_since(align_start);
  // On the hand-over frame, the joint refinement over every frame since the snap.
  const bool last = frames_since_snap_ + 1 > options_.frames_after_snap;
  const bool joint = !hand_over_now && last && options_.joint_refinement && !kept_frames_.empty();
  if (joint) {
    const auto joint_start = std::chrono::steady_clock::now();
    // With plain_starts, only the search set (after the plain starts) is refined and compared.
    const std::size_t first_refined = options_.plain_starts ? first_search_ : 0;
    for_hypotheses([&](CoarseInitializer& worker, std::size_t begin, std::size_t end) {
      refine_hypothesis_range(worker, begin, end);
    }, first_refined);
    timings_.joint_s += seconds_since(joint_start);
    if (options_.select_by_mean_visible_energy) {
      // Compared over all kept frames on their mean energy in view, the lowest wins outright,
      // among those that pass the odometry's checks; the plain choice when none does.
      std::size_t chosen = hypotheses_.size();
      for (std::size_t k = first_refined; k < hypotheses_.size(); ++k) {
        const Hypothesis& h = hypotheses_[k];
        if (h.inlier_fraction < options_.hand_over_min_inlier_fraction || h.rms > options_.hand_over_max_rms ||
            std::abs(h.a) > options_.hand_over_max_abs_affine_a)
          continue;
        if (chosen == hypotheses_.size() || h.energy < hypotheses_[chosen].energy) chosen = k;
      }
      best = chosen < hypotheses_.size() ? chosen : plain_choice();
    } else {
      best = plain_choice();
    }
  } else if (!search) {
    best = plain_choice();
  }
  kept_hypothesis_ = best;
  early_hand_over_ = hand_over_now;
  load(hypotheses_[best]);
  // The kept one's rms and inliers, on the residuals it was aligned with (refined: offset-free).
  offset_free_ = hypotheses_[best].offset_free;
  std::vector<double> rho(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i) rho[i] = points_[i].inverse_depth;
  update_neighbour_means();
  evaluate(0, frame, exposure, T_frame_first_, a_, b_, rho, false);
  for (std::size_t i = 0; i < points_.size(); ++i) points_[i].good = inliers_[i] != 0;
  return hand_over_now;
}

std::vector<std::pair<int, SE3>> CoarseInitializer::post_snap_poses() const {
  std::vector<std::pair<int, SE3>> poses;
  // Handed over by the plain path early: its frames were aligned one by one, as without the
  // search (the odometry keeps the poses it recorded then).
  if (kept_hypothesis_ >= hypotheses_.size() || early_hand_over_) return poses;
  const auto& track = hypotheses_[kept_hypothesis_].track;
  for (std::size_t f = 0; f < track.size() && f < kept_indices_.size(); ++f)
    poses.emplace_back(kept_indices_[f], track[f].T);
  return poses;
}

InitializerState CoarseInitializer::add_frame(std::shared_ptr<const ImagePyramid> frame, double exposure) {
  if (state_ != InitializerState::Tracking) return state_;
  ++frames_;
  bool early_hand_over = false;
  if (snapped_) {
    if (options_.joint_refinement) {
      kept_frames_.push_back(frame);
      kept_exposures_.push_back(exposure);
      kept_indices_.push_back(frames_);
    }
    if (align_hypotheses(*frame, exposure)) early_hand_over = true;
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
        hypotheses_.push_back({SE3(Eigen::Quaterniond::Identity(), t), a_, b_, points_, 0.0, {}, Eigen::Vector3d::Zero()});
        for (const double sign : {-1.0, 1.0})
          hypotheses_.push_back({SE3(q, sign * t.norm() * Eigen::Vector3d::UnitZ()), a_, b_, points_, 0.0, {}, Eigen::Vector3d::Zero()});
      }
      for (auto& h : hypotheses_) h.offset_free = offset_free_;
      const bool search = options_.direction_rings > 0 && !geometric;
      auto& search_set = search && options_.plain_hand_over_frames > 0 ? pending_ : hypotheses_;
      first_search_ = hypotheses_.size();
      if (search && options_.plain_starts) {
        // The starts on plain residuals (the path without the search: its choice is the current
        // state until the hand-over, and the fallback), and the same starts offset-free, in the
        // search set.
        for (auto& h : hypotheses_) {
          Hypothesis copy = h;
          copy.search = true;
          copy.offset_free = options_.patch_offset_invariant;
          h.offset_free = false;
          search_set.push_back(std::move(copy));
        }
      }
      if (search) {
        // Candidates with the camera centre's direction held on cones around the pre-snap one
        // (its rotation kept) while their depths converge, released in the joint refinement.
        const Eigen::Matrix3d R0 = T_frame_first_.rotation_matrix();
        const Eigen::Vector3d c0 = -(R0.transpose() * T_frame_first_.translation()).normalized();
        const Eigen::Vector3d e1 = c0.unitOrthogonal();
        const Eigen::Vector3d e2 = c0.cross(e1);
        const double norm = T_frame_first_.translation().norm();
        const double step = options_.direction_ring_step_deg;
        const int rings = options_.direction_rings;
        for (int ring = 0; ring <= rings; ++ring) {
          const int az_count = ring == 0 ? 1 : 6;
          for (int az = 0; az < az_count; ++az) {
            const double theta = ring * step * M_PI / 180.0;
            const double phi = (az + 0.5 * (ring % 2)) * 2.0 * M_PI / az_count;
            const Eigen::Vector3d u = std::cos(theta) * c0 + std::sin(theta) * (std::cos(phi) * e1 + std::sin(phi) * e2);
            Hypothesis h{SE3(T_frame_first_.unit_quaternion(), -(R0 * u) * norm), a_, b_, points_, 0.0, {}, u};
            h.search = true;
            h.offset_free = options_.patch_offset_invariant;
            // With the plain path's gate they wait until it has decided (align_hypotheses).
            search_set.push_back(std::move(h));
          }
        }
      }
      // The depth-regularised alignment starts on the next frame (more baseline): aligned on the
      // snap frame itself, the depths of the pre-snap pose wander along the small-baseline
      // ambiguity (room 50 W: 4.6 % of the path instead of 0.7 %).
    }
  }
  parallax_ = translational_parallax();
  if (snapped_ && (++frames_since_snap_ > options_.frames_after_snap || early_hand_over))
    state_ = InitializerState::Succeeded;
  return state_;
}

}  // namespace nirslam::odometry
