#include "nirslam/odometry/window_optimizer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace nirslam::odometry {

namespace {

// Geometry and brightness of one (host, target) pair, shared by all the host's points.
struct PairCache {
  Eigen::Matrix3d R;        // T_target_host at the current state
  Eigen::Vector3d t;
  Eigen::Matrix3d R_jacobian;  // at the first estimates (FEJ)
  Eigen::Vector3d t_jacobian;
  Matrix6d adjoint_jacobian;
  AffineTransfer affine;
  bool valid = false;
};

const FrameParameters& jacobian_state(const WindowFrame& f) {
  return f.first_estimate_fixed ? f.linearisation : f.state;
}

std::vector<PairCache> make_pairs(const std::vector<WindowFrame>& frames) {
  const std::size_t n = frames.size();
  std::vector<PairCache> pairs(n * n);
  for (std::size_t h = 0; h < n; ++h) {
    for (std::size_t t = 0; t < n; ++t) {
      if (h == t) continue;
      PairCache& p = pairs[h * n + t];
      const SE3 T_th = frames[t].state.T_cam_world * frames[h].state.T_cam_world.inverse();
      const SE3 T_th_jac = jacobian_state(frames[t]).T_cam_world * jacobian_state(frames[h]).T_cam_world.inverse();
      p.R = T_th.rotation_matrix();
      p.t = T_th.translation();
      p.R_jacobian = T_th_jac.rotation_matrix();
      p.t_jacobian = T_th_jac.translation();
      p.adjoint_jacobian = adjoint(T_th_jac);
      p.affine = affine_transfer(frames[h].state.affine_a, frames[h].state.affine_b, frames[h].exposure,
                                 frames[t].state.affine_a, frames[t].state.affine_b, frames[t].exposure);
      p.valid = true;
    }
  }
  return pairs;
}

// A residual's derivatives by the pair's 9 relative parameters (xi of T_target_host, a_t, b_t,
// b_h): the first 8 are the target's own; b_h is kept apart because its derivative s g (I_h - b_h)
// / (I_h - b_h) = s g carries the point's lamp factor g, so no per-pair constant maps it.
using Vector9d = Eigen::Matrix<double, 9, 1>;
using Matrix9d = Eigen::Matrix<double, 9, 9>;
using Matrix89d = Eigen::Matrix<double, 8, 9>;
using Matrix94d = Eigen::Matrix<double, 9, 4>;

// Maps the 9 relative parameters to the host's 8 parameters (xi_h, a_h, b_h).
Matrix89d host_map(const PairCache& p) {
  Matrix89d M = Matrix89d::Zero();
  M.topLeftCorner<6, 6>() = -p.adjoint_jacobian.transpose();
  M(6, 6) = -1.0;
  M(7, 8) = 1.0;
  return M;
}

// The lamp's factor g for a point seen from a pair at the current state (1 when off).
double lamp_value(const WindowOptions& o, const LevelCamera& camera, const WindowPoint& point, const Eigen::Matrix3d& R,
                  const Eigen::Vector3d& t) {
  return o.lamp.enabled ? lamp_factor_value(camera.unproject(point.pixel), point.inverse_depth, R, t, o.lamp,
                                            point.normal ? &*point.normal : nullptr)
                        : 1.0;
}

// A frame's priors on its affine brightness and (when set) its pose, at its 8-block offset `o`.
void add_frame_priors(const WindowFrame& f, Eigen::Index o, Eigen::MatrixXd& H, Eigen::VectorXd& b) {
  H(o + 6, o + 6) += f.affine_a_prior_weight;
  b(o + 6) += f.affine_a_prior_weight * f.state.affine_a;
  H(o + 7, o + 7) += f.affine_b_prior_weight;
  b(o + 7) += f.affine_b_prior_weight * f.state.affine_b;
  if (f.pose_prior_weight > 0.0) {
    H.block<6, 6>(o, o).diagonal().array() += f.pose_prior_weight;
    b.segment<6>(o) += f.pose_prior_weight * (f.state.T_cam_world * f.pose_prior.inverse()).log();
  }
}

}  // namespace

WindowOptimizer::WindowOptimizer(const LevelCamera& camera, const WindowOptions& options)
    : camera_(camera), options_(options) {}

int WindowOptimizer::index_of(std::int64_t id) const {
  for (std::size_t i = 0; i < frames_.size(); ++i)
    if (frames_[i].id == id) return static_cast<int>(i);
  return -1;
}

WindowFrame& WindowOptimizer::add_frame(WindowFrame frame) {
  frames_.push_back(std::move(frame));
  const auto n = static_cast<Eigen::Index>(8 * frames_.size());
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  if (H_prior_.size() > 0) {
    H.topLeftCorner(H_prior_.rows(), H_prior_.cols()) = H_prior_;
    b.head(b_prior_.size()) = b_prior_;
  }
  H_prior_ = std::move(H);
  b_prior_ = std::move(b);
  return frames_.back();
}

void WindowOptimizer::connect_to_all(WindowPoint& point, std::int64_t host_id) const {
  point.residuals.clear();
  for (const auto& f : frames_) {
    if (f.id == host_id) continue;
    PointResidual r;
    r.target_id = f.id;
    point.residuals.push_back(r);
  }
}

int WindowOptimizer::point_count() const {
  int n = 0;
  for (const auto& f : frames_) n += static_cast<int>(f.points.size());
  return n;
}

Vector8d WindowOptimizer::prior_delta(const WindowFrame& frame) const {
  Vector8d d = Vector8d::Zero();
  if (!frame.first_estimate_fixed) return d;
  d.head<6>() = (frame.state.T_cam_world * frame.linearisation.T_cam_world.inverse()).log();
  d[6] = frame.state.affine_a - frame.linearisation.affine_a;
  d[7] = frame.state.affine_b - frame.linearisation.affine_b;
  return d;
}

double WindowOptimizer::energy() { return evaluate_residuals(nullptr, nullptr) + frame_prior_energy(); }

// Per-pair 9x9 blocks of the relative parameters (xi of T_target_host, a_t, b_t, b_h), one set
// per worker thread, summed by the caller.
struct WindowOptimizer::Linearization {
  std::array<std::vector<Matrix9d>, 2> H_rel;
  std::array<std::vector<Vector9d>, 2> b_rel;
  std::vector<Matrix89d> host_maps;  // per pair: relative parameters -> the host's
};

double WindowOptimizer::evaluate_residuals(const std::vector<int>* only_hosts, Linearization* lin) {
  const std::size_t n = frames_.size();
  const auto pairs = make_pairs(frames_);
  if (lin != nullptr) {
    lin->host_maps.assign(n * n, Matrix89d::Zero());
    for (std::size_t i = 0; i < n * n; ++i)
      if (pairs[i].valid) lin->host_maps[i] = host_map(pairs[i]);
    for (std::size_t wk = 0; wk < 2; ++wk) {
      lin->H_rel[wk].assign(n * n, Matrix9d::Zero());
      lin->b_rel[wk].assign(n * n, Vector9d::Zero());
    }
  }
  const double k = options_.huber_threshold;
  const double c2 = options_.gradient_weight_c * options_.gradient_weight_c;
  const double outlier = options_.outlier_energy * kPatternSize;

  std::vector<std::pair<std::size_t, WindowPoint*>> items;
  for (std::size_t h = 0; h < n; ++h) {
    if (only_hosts != nullptr &&
        std::find(only_hosts->begin(), only_hosts->end(), static_cast<int>(h)) == only_hosts->end())
      continue;
    for (auto& point : frames_[h].points) items.emplace_back(h, &point);
  }
  struct Sums {
    double energy = 0.0, inlier_energy = 0.0;
    int inlier_count = 0;
  };
  std::array<Sums, 2> sums{};
  // Two halves, the caller's thread and the helper; small counts (tests) stay on the caller.
  split_in_two(*helper_, items.size(), items.size() / 2, 256, [&](std::size_t begin, std::size_t end, int worker) {
    Sums& acc = sums[static_cast<std::size_t>(worker)];
    for (std::size_t item = begin; item < end; ++item) {
      const std::size_t h = items[item].first;
      WindowPoint& point = *items[item].second;
      const double d_prior = point.inverse_depth - point.inverse_depth_prior_mean;
      acc.energy += point.inverse_depth_prior_weight * d_prior * d_prior;
      if (lin != nullptr) {
        point.H_pp = point.inverse_depth_prior_weight;
        point.b_p = point.inverse_depth_prior_weight * d_prior;
        point.H_host_point.setZero();
      }
      for (auto& res : point.residuals) {
        res.inlier = false;
        if (lin != nullptr) res.H_target_point.setZero();
        const int t = index_of(res.target_id);
        if (t < 0) continue;
        const std::size_t pair_index = h * n + static_cast<std::size_t>(t);
        const PairCache& p = pairs[pair_index];
        const PyramidLevel& target = frames_[static_cast<std::size_t>(t)].pyramid->level(0);
        // A residual that cannot be evaluated counts as an outlier.
        res.energy = outlier;

        // Linearisation only: the geometric Jacobian of the centre pixel, at the first
        // estimates, serves the whole pattern (as in DSO): the pattern spans a few pixels of one
        // surface. The lamp: g at the current state, its derivatives at the first estimates (as
        // the warp's), from the centre pixel for the whole pattern.
        Matrix26d d_pose = Matrix26d::Zero();
        Eigen::Vector2d d_rho = Eigen::Vector2d::Zero();
        LampFactor lamp;
        const Eigen::Vector3d* normal = point.normal ? &*point.normal : nullptr;
        if (lin != nullptr) {
          Warp wj;
          if (!warp_pixel(camera_, p.R_jacobian, p.t_jacobian, point.pixel, point.inverse_depth, wj)) {
            acc.energy += outlier;
            continue;
          }
          warp_jacobians(camera_, wj, p.t_jacobian, d_pose, d_rho);
          if (options_.lamp.enabled &&
              !lamp_factor(camera_.unproject(point.pixel), point.inverse_depth, p.R_jacobian, p.t_jacobian,
                           options_.lamp, lamp, normal)) {
            acc.energy += outlier;
            continue;
          }
        }
        lamp.g = lamp_value(options_, camera_, point, p.R, p.t);
        const double g_scale = lamp.g * p.affine.scale;
        const double beam = target_beam_scale(camera_.unproject(point.pixel), point.inverse_depth, p.R, p.t, options_.lamp);

        // Every pixel's Jacobian is J = M u with u = (g_x, g_y, host term, 1) and M fixed for the
        // residual (the centre pixel's geometry serves the pattern), so the pattern's sums are
        // kept as W u u^T and W r u (4x4 and 4) and mapped through M once per residual.
        Eigen::Matrix4d S = Eigen::Matrix4d::Zero();
        Eigen::Vector4d s_r = Eigen::Vector4d::Zero();
        double energy = 0.0;
        bool in_view = true;
        for (int i = 0; i < kPatternSize; ++i) {
          const auto& o = kPattern[static_cast<std::size_t>(i)];
          const Eigen::Vector2d px = point.pixel + Eigen::Vector2d(o[0], o[1]);
          Warp w;
          if (!warp_pixel(camera_, p.R, p.t, px, point.inverse_depth, w) ||
              !camera_.inside(w.pixel.x(), w.pixel.y(), 1.0)) {
            in_view = false;
            break;
          }
          const Eigen::Vector3f s = target.interpolate(static_cast<float>(w.pixel.x()), static_cast<float>(w.pixel.y()));
          const double host_term = g_scale * (point.host_intensity[static_cast<std::size_t>(i)] - p.affine.b_host);
          const double r = s[0] - host_term - p.affine.b_target;
          const double r_beam = r / beam;
          const double wg = c2 / (c2 + static_cast<double>(s.tail<2>().squaredNorm()) / (beam * beam));
          const double hw = huber_weight(r_beam, k);
          energy += wg * hw * r_beam * r_beam * (2.0 - hw);
          if (lin == nullptr) continue;
          const double W = wg * hw / (beam * beam);
          const Eigen::Vector4d u(static_cast<double>(s[1]), static_cast<double>(s[2]), host_term, 1.0);
          S.noalias() += (W * u) * u.transpose();
          s_r += (W * r) * u;
        }
        if (in_view) res.energy = std::min(energy, outlier);
        acc.energy += res.energy;
        if (!in_view || energy > outlier) continue;
        res.inlier = true;
        acc.inlier_energy += energy;
        acc.inlier_count += kPatternSize;
        if (lin == nullptr) continue;
        Matrix94d M = Matrix94d::Zero();  // d r / d (relative parameters) = M u
        M.block<6, 1>(0, 0) = d_pose.row(0).transpose();
        M.block<6, 1>(0, 1) = d_pose.row(1).transpose();
        M.block<6, 1>(0, 2) = -lamp.d_log_g_d_pose.transpose();
        M(6, 2) = -1.0;
        M(7, 3) = -1.0;
        M(8, 3) = g_scale;
        const Eigen::Vector4d v(d_rho.x(), d_rho.y(), -lamp.d_log_g_d_rho, 0.0);  // d r / d rho = v . u
        const Matrix94d MS = M * S;
        const Eigen::Vector4d Sv = S * v;
        const Vector9d H_rp = M * Sv;
        lin->H_rel[static_cast<std::size_t>(worker)][pair_index].noalias() += MS * M.transpose();
        lin->b_rel[static_cast<std::size_t>(worker)][pair_index].noalias() += M * s_r;
        point.H_host_point += lin->host_maps[pair_index] * H_rp;
        res.H_target_point = H_rp.head<8>();
        point.H_pp += v.dot(Sv);
        point.b_p += v.dot(s_r);
      }
    }
  });
  const double inlier_energy = sums[0].inlier_energy + sums[1].inlier_energy;
  const int inlier_count = sums[0].inlier_count + sums[1].inlier_count;
  last_rms_ = inlier_count > 0 ? std::sqrt(inlier_energy / inlier_count) : 0.0;
  return sums[0].energy + sums[1].energy;
}

double WindowOptimizer::linearize(Eigen::MatrixXd& H, Eigen::VectorXd& b, double lambda,
                                  const std::vector<int>* only_hosts, bool include_priors) {
  const double energy = linearize_frames(H, b, only_hosts, include_priors);
  reduce(H, b, lambda, only_hosts);
  return energy;
}

double WindowOptimizer::linearize_frames(Eigen::MatrixXd& H, Eigen::VectorXd& b, const std::vector<int>* only_hosts,
                                         bool include_priors) {
  const std::size_t n = frames_.size();
  const auto N = static_cast<Eigen::Index>(8 * n);
  H.setZero(N, N);
  b.setZero(N);
  Linearization lin;
  const double residual_energy = evaluate_residuals(only_hosts, &lin);
  const std::vector<Matrix89d>& host_maps = lin.host_maps;
  std::vector<Matrix9d> H_rel(n * n);
  std::vector<Vector9d> b_rel(n * n);
  for (std::size_t i = 0; i < n * n; ++i) {
    H_rel[i] = lin.H_rel[0][i] + lin.H_rel[1][i];
    b_rel[i] = lin.b_rel[0][i] + lin.b_rel[1][i];
  }
  for (std::size_t h = 0; h < n; ++h) {
    for (std::size_t t = 0; t < n; ++t) {
      if (h == t) continue;
      const std::size_t i = h * n + t;
      const Matrix89d& M = host_maps[i];
      const auto ih = static_cast<Eigen::Index>(8 * h);
      const auto it = static_cast<Eigen::Index>(8 * t);
      const Eigen::Matrix<double, 9, 8> H_rel_target = H_rel[i].leftCols<8>();  // columns of the target's 8
      H.block<8, 8>(ih, ih) += M * H_rel[i] * M.transpose();
      H.block<8, 8>(ih, it) += M * H_rel_target;
      H.block<8, 8>(it, ih) += H_rel_target.transpose() * M.transpose();
      H.block<8, 8>(it, it) += H_rel[i].topLeftCorner<8, 8>();
      b.segment<8>(ih) += M * b_rel[i];
      b.segment<8>(it) += b_rel[i].head<8>();
    }
  }

  if (include_priors) {
    for (std::size_t i = 0; i < n; ++i) add_frame_priors(frames_[i], static_cast<Eigen::Index>(8 * i), H, b);
    Eigen::VectorXd delta(N);
    for (std::size_t i = 0; i < n; ++i) delta.segment<8>(static_cast<Eigen::Index>(8 * i)) = prior_delta(frames_[i]);
    H += H_prior_;
    b += b_prior_ + H_prior_ * delta;
  }
  return residual_energy + (include_priors ? frame_prior_energy() : 0.0);
}

void WindowOptimizer::reduce(Eigen::MatrixXd& H, Eigen::VectorXd& b, double lambda, const std::vector<int>* only_hosts) {
  const std::size_t n = frames_.size();
  auto hosts_to_use = [&](std::size_t h) {
    return only_hosts == nullptr ||
           std::find(only_hosts->begin(), only_hosts->end(), static_cast<int>(h)) != only_hosts->end();
  };
  if (lambda > 0.0) H.diagonal() *= 1.0 + lambda;

  // Schur complement over the points: each couples its host and its inlier targets. Only the
  // blocks on and below the diagonal are updated (H is symmetric; the upper ones are copied from
  // them at the end). Split over two threads by the block columns of H (and segments of b) each
  // owns, those of even / odd frames (columns: H is column-major, so the threads write apart):
  // both walk all points in the same order and each updates only its own, so every entry of H and
  // b gets the same subtractions in the same order as on one thread (results identical to the bit).
  auto schur_rows = [&](std::size_t parity) {
    std::vector<std::pair<Eigen::Index, const Vector8d*>> coupling;
    for (std::size_t h = 0; h < n; ++h) {
      if (!hosts_to_use(h)) continue;
      for (auto& point : frames_[h].points) {
        if (point.H_pp <= 0.0) continue;
        const double inverse_H_pp = 1.0 / (point.H_pp * (1.0 + lambda) + 1e-12);
        coupling.clear();
        coupling.emplace_back(static_cast<Eigen::Index>(8 * h), &point.H_host_point);
        for (const auto& res : point.residuals) {
          if (!res.inlier) continue;
          coupling.emplace_back(static_cast<Eigen::Index>(8 * index_of(res.target_id)), &res.H_target_point);
        }
        for (const auto& [ib, cb] : coupling) {
          if (static_cast<std::size_t>(ib / 8) % 2 != parity) continue;
          const Vector8d cb_scaled = *cb * inverse_H_pp;
          b.segment<8>(ib) -= cb_scaled * point.b_p;
          for (const auto& [ia, ca] : coupling)
            if (ia >= ib) H.block<8, 8>(ia, ib).noalias() -= *ca * cb_scaled.transpose();
        }
      }
    }
  };
  helper_->run([&] { schur_rows(0); }, [&] { schur_rows(1); });
  for (Eigen::Index col = 1; col < H.cols(); ++col)
    for (Eigen::Index row = 0; row < col; ++row) H(row, col) = H(col, row);
}

double WindowOptimizer::frame_prior_energy() const {
  const std::size_t n = frames_.size();
  double e = 0.0;
  for (const WindowFrame& f : frames_) {
    e += f.affine_a_prior_weight * f.state.affine_a * f.state.affine_a;
    e += f.affine_b_prior_weight * f.state.affine_b * f.state.affine_b;
    if (f.pose_prior_weight > 0.0)
      e += f.pose_prior_weight * (f.state.T_cam_world * f.pose_prior.inverse()).log().squaredNorm();
  }
  Eigen::VectorXd delta(static_cast<Eigen::Index>(8 * n));
  for (std::size_t i = 0; i < n; ++i) delta.segment<8>(static_cast<Eigen::Index>(8 * i)) = prior_delta(frames_[i]);
  return e + 2.0 * b_prior_.dot(delta) + delta.dot(H_prior_ * delta);
}

Eigen::VectorXd WindowOptimizer::solve(const Eigen::MatrixXd& H, const Eigen::VectorXd& b, double lambda) {
  Eigen::VectorXd dx = H.ldlt().solve(-b);
  // Back-substitute the points, for apply_step.
  const std::size_t n = frames_.size();
  for (std::size_t h = 0; h < n; ++h) {
    for (auto& point : frames_[h].points) {
      if (point.H_pp <= 0.0) {
        point.step = 0.0;
        continue;
      }
      double rhs = point.b_p + point.H_host_point.dot(dx.segment<8>(static_cast<Eigen::Index>(8 * h)));
      for (const auto& res : point.residuals)
        if (res.inlier) rhs += res.H_target_point.dot(dx.segment<8>(static_cast<Eigen::Index>(8 * index_of(res.target_id))));
      point.step = -rhs / (point.H_pp * (1.0 + lambda) + 1e-12);
    }
  }
  return dx;
}

Eigen::VectorXd WindowOptimizer::compute_step(double lambda) {
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  linearize(H, b, lambda, nullptr, true);
  return solve(H, b, lambda);
}

void WindowOptimizer::apply_step(const Eigen::VectorXd& dx, double /*lambda*/) {
  for (std::size_t i = 0; i < frames_.size(); ++i) {
    WindowFrame& f = frames_[i];
    const auto o = static_cast<Eigen::Index>(8 * i);
    f.state.T_cam_world = SE3::exp(dx.segment<6>(o)) * f.state.T_cam_world;
    f.state.affine_a += dx(o + 6);
    f.state.affine_b += dx(o + 7);
    for (auto& point : f.points) point.inverse_depth = std::clamp(point.inverse_depth + point.step, 1e-4, 1e3);
  }
}

void WindowOptimizer::backup() {
  point_scratch_.clear();
  residual_scratch_.clear();
  for (auto& f : frames_) {
    f.backup = f.state;
    for (auto& p : f.points) {
      p.backup = p.inverse_depth;
      point_scratch_.push_back({p.H_pp, p.b_p, p.H_host_point});
      for (const auto& r : p.residuals) residual_scratch_.push_back({r.inlier, r.energy, r.H_target_point});
    }
  }
  rms_backup_ = last_rms_;
}

void WindowOptimizer::restore() {
  std::size_t point = 0;
  std::size_t residual = 0;
  for (auto& f : frames_) {
    f.state = f.backup;
    for (auto& p : f.points) {
      p.inverse_depth = p.backup;
      const PointScratch& ps = point_scratch_[point++];
      p.H_pp = ps.H_pp;
      p.b_p = ps.b_p;
      p.H_host_point = ps.H_host_point;
      for (auto& r : p.residuals) {
        const ResidualScratch& rs = residual_scratch_[residual++];
        r.inlier = rs.inlier;
        r.energy = rs.energy;
        r.H_target_point = rs.H_target_point;
      }
    }
  }
  last_rms_ = rms_backup_;
}

WindowStatistics WindowOptimizer::optimize(int iterations) {
  WindowStatistics stats;
  if (frames_.size() < 2) return stats;
  // Each linearisation also gives the energy at its state, so a step is judged by linearising
  // at its result: one pass over the residuals per accepted iteration. A rejected step restores
  // the state and the linearisation it had (the frame system before damping, the points' blocks
  // and residual flags): the same as linearising there again, without the pass.
  double lambda = options_.initial_lambda;
  Eigen::MatrixXd H_frames;  // at the kept state, undamped, points not yet eliminated
  Eigen::VectorXd b_frames;
  double e = linearize_frames(H_frames, b_frames, nullptr, true);
  Eigen::MatrixXd H = H_frames;
  Eigen::VectorXd b = b_frames;
  reduce(H, b, lambda, nullptr);
  stats.initial_energy = e;
  Eigen::MatrixXd H_trial;
  Eigen::VectorXd b_trial;
  for (int it = 0; it < iterations; ++it) {
    const Eigen::VectorXd dx = solve(H, b, lambda);
    if (!dx.allFinite()) break;
    backup();
    apply_step(dx, lambda);
    ++stats.iterations;
    const double next_lambda = std::max(lambda * 0.25, 1e-6);
    const double e_new = linearize_frames(H_trial, b_trial, nullptr, true);
    if (e_new < e) {
      const bool converged = e - e_new < 1e-3 * e;
      e = e_new;
      lambda = next_lambda;
      if (converged) break;
      H_frames.swap(H_trial);
      b_frames.swap(b_trial);
    } else {
      restore();
      lambda *= 8.0;
      if (lambda > 1e4 || it + 1 == iterations) break;
    }
    H = H_frames;
    b = b_frames;
    reduce(H, b, lambda, nullptr);
  }
  stats.final_energy = e;
  for (const auto& f : frames_)
    for (const auto& p : f.points)
      for (const auto& r : p.residuals) stats.residuals += r.inlier ? 1 : 0;
  return stats;
}

void WindowOptimizer::add_points_to_prior() {
  for (auto& f : frames_) {
    if (!f.first_estimate_fixed) {
      f.first_estimate_fixed = true;
      f.linearisation = f.state;
    }
  }
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  linearize(H, b, 0.0, nullptr, false);
  const std::size_t n = frames_.size();
  Eigen::VectorXd delta(static_cast<Eigen::Index>(8 * n));
  for (std::size_t i = 0; i < n; ++i) delta.segment<8>(static_cast<Eigen::Index>(8 * i)) = prior_delta(frames_[i]);
  H_prior_ += H;
  b_prior_ += b - H * delta;
}

WindowFrame WindowOptimizer::marginalize_frame(int index) {
  const std::size_t n = frames_.size();
  const auto m = static_cast<std::size_t>(index);
  // Every frame the prior will touch keeps its Jacobians at the current estimate from now on.
  for (auto& f : frames_) {
    if (!f.first_estimate_fixed) {
      f.first_estimate_fixed = true;
      f.linearisation = f.state;
    }
  }
  // The marginalised frame's points, Schur-complemented, plus the frame's own priors.
  Eigen::MatrixXd H;
  Eigen::VectorXd b;
  const std::vector<int> hosts{index};
  linearize(H, b, 0.0, &hosts, false);
  add_frame_priors(frames_[m], static_cast<Eigen::Index>(8 * m), H, b);
  // Moved to the first estimates, where the prior lives.
  Eigen::VectorXd delta(static_cast<Eigen::Index>(8 * n));
  for (std::size_t i = 0; i < n; ++i) delta.segment<8>(static_cast<Eigen::Index>(8 * i)) = prior_delta(frames_[i]);
  H_prior_ += H;
  b_prior_ += b - H * delta;

  // Residuals of other points into the marginalised frame are dropped (DSO does the same).
  const std::int64_t id = frames_[m].id;
  for (auto& f : frames_) {
    for (auto& p : f.points) {
      p.residuals.erase(std::remove_if(p.residuals.begin(), p.residuals.end(),
                                       [id](const PointResidual& r) { return r.target_id == id; }),
                        p.residuals.end());
    }
  }

  // Schur complement of the frame's block out of the prior.
  const auto N = static_cast<Eigen::Index>(8 * n);
  const auto om = static_cast<Eigen::Index>(8 * m);
  std::vector<Eigen::Index> keep;
  for (Eigen::Index i = 0; i < N; ++i)
    if (i < om || i >= om + 8) keep.push_back(i);
  const auto K = static_cast<Eigen::Index>(keep.size());
  Eigen::MatrixXd H_kk(K, K);
  Eigen::MatrixXd H_km(K, 8);
  Eigen::VectorXd b_k(K);
  for (Eigen::Index i = 0; i < K; ++i) {
    b_k(i) = b_prior_(keep[static_cast<std::size_t>(i)]);
    for (Eigen::Index j = 0; j < K; ++j) H_kk(i, j) = H_prior_(keep[static_cast<std::size_t>(i)], keep[static_cast<std::size_t>(j)]);
    for (Eigen::Index j = 0; j < 8; ++j) H_km(i, j) = H_prior_(keep[static_cast<std::size_t>(i)], om + j);
  }
  const Matrix8d H_mm = H_prior_.block<8, 8>(om, om);
  const Vector8d b_m = b_prior_.segment<8>(om);
  // Pseudo-inverse: directions the prior does not constrain (gauge) carry no information.
  Eigen::SelfAdjointEigenSolver<Matrix8d> eig(0.5 * (H_mm + H_mm.transpose()));
  const double cutoff = std::max(1e-12, eig.eigenvalues().maxCoeff() * 1e-12);
  Vector8d inv_values;
  for (int i = 0; i < 8; ++i) inv_values[i] = eig.eigenvalues()[i] > cutoff ? 1.0 / eig.eigenvalues()[i] : 0.0;
  const Matrix8d H_mm_inv = eig.eigenvectors() * inv_values.asDiagonal() * eig.eigenvectors().transpose();
  H_prior_ = H_kk - H_km * H_mm_inv * H_km.transpose();
  H_prior_ = 0.5 * (H_prior_ + H_prior_.transpose()).eval();
  b_prior_ = b_k - H_km * H_mm_inv * b_m;

  WindowFrame removed = std::move(frames_[m]);
  frames_.erase(frames_.begin() + static_cast<std::ptrdiff_t>(m));
  return removed;
}

bool WindowOptimizer::optimize_point(int host_index, WindowPoint& point, int iterations, int min_inliers) {
  const auto h = static_cast<std::size_t>(host_index);
  const WindowFrame& host = frames_[h];
  const double k = options_.huber_threshold;
  const double c2 = options_.gradient_weight_c * options_.gradient_weight_c;
  const double outlier = options_.outlier_energy * kPatternSize;
  struct Target {
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    AffineTransfer affine;
    const PyramidLevel* image;
  };
  std::vector<Target> targets;
  for (const auto& res : point.residuals) {
    const int ti = index_of(res.target_id);
    const WindowFrame& f = frames_[static_cast<std::size_t>(ti)];
    const SE3 T = f.state.T_cam_world * host.state.T_cam_world.inverse();
    targets.push_back({T.rotation_matrix(), T.translation(),
                       affine_transfer(host.state.affine_a, host.state.affine_b, host.exposure, f.state.affine_a,
                                       f.state.affine_b, f.exposure),
                       &f.pyramid->level(0)});
  }
  // Energy, gradient and Hessian in rho; counts inlier residuals.
  auto evaluate = [&](double rho, double& H, double& g, int& inliers) {
    H = 0.0;
    g = 0.0;
    inliers = 0;
    double total = 0.0;
    const Eigen::Vector3d ray = camera_.unproject(point.pixel);
    for (const Target& tg : targets) {
      double e = 0.0;
      double H_r = 0.0;
      double g_r = 0.0;
      bool in_view = true;
      LampFactor lamp;
      if (options_.lamp.enabled &&
          !lamp_factor(ray, rho, tg.R, tg.t, options_.lamp, lamp, point.normal ? &*point.normal : nullptr))
        in_view = false;
      const double beam = target_beam_scale(ray, rho, tg.R, tg.t, options_.lamp);
      for (int i = 0; i < kPatternSize && in_view; ++i) {
        const auto& o = kPattern[static_cast<std::size_t>(i)];
        const Eigen::Vector2d px = point.pixel + Eigen::Vector2d(o[0], o[1]);
        Warp w;
        if (!warp_pixel(camera_, tg.R, tg.t, px, rho, w) || !camera_.inside(w.pixel.x(), w.pixel.y(), 1.0)) {
          in_view = false;
          break;
        }
        const Eigen::Vector3f s = tg.image->interpolate(static_cast<float>(w.pixel.x()), static_cast<float>(w.pixel.y()));
        const double host_term =
            lamp.g * tg.affine.scale * (point.host_intensity[static_cast<std::size_t>(i)] - tg.affine.b_host);
        const double r = s[0] - host_term - tg.affine.b_target;
        const double r_beam = r / beam;
        const double hw = huber_weight(r_beam, k);
        const double wg = c2 / (c2 + static_cast<double>(s.tail<2>().squaredNorm()) / (beam * beam));
        const double W = wg * hw / (beam * beam);
        e += wg * hw * r_beam * r_beam * (2.0 - hw);
        Matrix26d d_pose;
        Eigen::Vector2d d_rho;
        warp_jacobians(camera_, w, tg.t, d_pose, d_rho);
        const double J = s.tail<2>().cast<double>().dot(d_rho) - host_term * lamp.d_log_g_d_rho;
        H_r += W * J * J;
        g_r += W * J * r;
      }
      if (!in_view || e > outlier) {
        total += outlier;
        continue;
      }
      ++inliers;
      total += e;
      H += H_r;
      g += g_r;
    }
    return total;
  };
  double H = 0.0;
  double g = 0.0;
  int inliers = 0;
  double energy = evaluate(point.inverse_depth, H, g, inliers);
  double lambda = 0.1;
  for (int it = 0; it < iterations && H > 0.0; ++it) {
    const double rho_new = std::clamp(point.inverse_depth - g / (H * (1.0 + lambda)), 1e-4, 1e3);
    double H_new = 0.0;
    double g_new = 0.0;
    int inliers_new = 0;
    const double energy_new = evaluate(rho_new, H_new, g_new, inliers_new);
    if (energy_new < energy) {
      point.inverse_depth = rho_new;
      energy = energy_new;
      H = H_new;
      g = g_new;
      inliers = inliers_new;
      lambda *= 0.5;
    } else {
      lambda *= 5.0;
    }
  }
  return inliers >= min_inliers;
}

std::vector<std::pair<std::int64_t, WindowPoint>> WindowOptimizer::remove_bad_points(int min_inliers,
                                                                                     bool out_of_newest) {
  std::vector<std::pair<std::int64_t, WindowPoint>> removed;
  if (frames_.empty()) return removed;
  const std::int64_t newest = frames_.back().id;
  for (auto& f : frames_) {
    auto keep_end = std::stable_partition(f.points.begin(), f.points.end(), [&](const WindowPoint& p) {
      int inliers = 0;
      bool seen_by_newest = f.id == newest;
      for (const auto& r : p.residuals) {
        inliers += r.inlier ? 1 : 0;
        if (r.target_id == newest && r.inlier) seen_by_newest = true;
      }
      if (out_of_newest && !seen_by_newest) return false;
      return inliers >= min_inliers || p.residuals.empty();
    });
    for (auto it = keep_end; it != f.points.end(); ++it) removed.emplace_back(f.id, std::move(*it));
    f.points.erase(keep_end, f.points.end());
  }
  return removed;
}

}  // namespace nirslam::odometry
