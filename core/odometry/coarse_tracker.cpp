#include "nirslam/odometry/coarse_tracker.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

namespace nirslam::odometry {

CoarseTracker::CoarseTracker(std::vector<LevelCamera> cameras, const CoarseTrackerOptions& options)
    : cameras_(std::move(cameras)), options_(options) {}

void CoarseTracker::set_reference(std::shared_ptr<const ImagePyramid> pyramid, double affine_a, double affine_b,
                                  double exposure, const std::vector<ReferencePoint>& points) {
  reference_ = std::move(pyramid);
  reference_a_ = affine_a;
  reference_b_ = affine_b;
  reference_exposure_ = exposure;
  const int levels = std::min(reference_->levels(), static_cast<int>(cameras_.size()));
  levels_.assign(static_cast<std::size_t>(levels), {});
  // Sparse inverse depth maps per level: points falling into one coarse pixel are averaged, so
  // coarse levels get fewer, better supported points (DSO's makeCoarseDepthL0).
  for (int l = 0; l < levels; ++l) {
    const PyramidLevel& image = reference_->level(l);
    const LevelCamera& cam = cameras_[static_cast<std::size_t>(l)];
    std::vector<float> sum(static_cast<std::size_t>(image.width * image.height), 0.0f);
    std::vector<int> count(sum.size(), 0);
    std::vector<Eigen::Vector3f> normal_sum(sum.size(), Eigen::Vector3f::Zero());
    const double scale = 1.0 / static_cast<double>(1 << l);
    for (const auto& p : points) {
      const int x = static_cast<int>(std::lround((p.pixel.x() + 0.5) * scale - 0.5));
      const int y = static_cast<int>(std::lround((p.pixel.y() + 0.5) * scale - 0.5));
      if (!cam.inside(x, y, 2.0)) continue;
      sum[static_cast<std::size_t>(y * image.width + x)] += static_cast<float>(p.inverse_depth);
      normal_sum[static_cast<std::size_t>(y * image.width + x)] += p.normal.cast<float>();
      ++count[static_cast<std::size_t>(y * image.width + x)];
    }
    auto& out = levels_[static_cast<std::size_t>(l)];
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        const auto i = static_cast<std::size_t>(y * image.width + x);
        if (count[i] == 0) continue;
        // Normals average too; unknown ones (zero) count for nothing, and a mean that is no
        // longer near unit length (points of different surfaces) counts as unknown.
        Eigen::Vector3f n = normal_sum[i] / static_cast<float>(count[i]);
        n = n.norm() > 0.7f ? n.normalized().eval() : Eigen::Vector3f::Zero();
        out.push_back({static_cast<float>(x), static_cast<float>(y), sum[i] / static_cast<float>(count[i]),
                       image.data[i][0], n});
      }
    }
  }
}

int CoarseTracker::accumulate(int level, const ImagePyramid& frame, double exposure, const SE3& T, double a,
                              double b, double cutoff, Matrix8d* H, Vector8d* g, double& energy,
                              int& projected) const {
  const LevelCamera& cam = cameras_[static_cast<std::size_t>(level)];
  const PyramidLevel& image = frame.level(level);
  const Eigen::Matrix3d R = T.rotation_matrix();
  const Eigen::Vector3d t = T.translation();
  const double s = std::exp(a - reference_a_) * exposure / reference_exposure_;
  const double k = options_.huber_threshold;
  const double c2 = options_.gradient_weight_c * options_.gradient_weight_c;
  if (H != nullptr) {
    H->setZero();
    g->setZero();
  }
  energy = 0.0;
  projected = 0;
  int inliers = 0;
  Matrix8d H_local = Matrix8d::Zero();
  const std::vector<LevelPoint>& points = levels_[static_cast<std::size_t>(level)];
  terms_.resize(points.size());
  // Each point's residual and Jacobian alone (two threads on the fine levels)...
  auto point_terms = [&](std::size_t begin, std::size_t end, int) {
    for (std::size_t i = begin; i < end; ++i) {
      const LevelPoint& p = points[i];
      PointTerm& term = terms_[i];
      term.kind = 0;
      Warp w;
      if (!warp_pixel(cam, R, t, Eigen::Vector2d(p.u, p.v), p.inverse_depth, w)) continue;
      if (!cam.inside(w.pixel.x(), w.pixel.y(), 2.0)) continue;
      term.kind = 1;
      const Eigen::Vector3f sample = image.interpolate(static_cast<float>(w.pixel.x()), static_cast<float>(w.pixel.y()));
      LampFactor lamp;
      const Eigen::Vector3d ray = cam.unproject(Eigen::Vector2d(p.u, p.v));
      if (options_.lamp.enabled) {
        const Eigen::Vector3d normal = p.normal.cast<double>();
        if (!lamp_factor(ray, p.inverse_depth, R, t, options_.lamp, lamp,
                         p.normal.isZero() ? nullptr : &normal))
          continue;
      }
      const double host_term = s * lamp.g * (p.reference_intensity - reference_b_);
      const double r = sample[0] - host_term - b;
      const double beam = target_beam_scale(ray, p.inverse_depth, R, t, options_.lamp);
      const double r_beam = r / beam;
      if (std::abs(r_beam) > cutoff) {
        term.kind = 2;
        continue;
      }
      term.kind = 3;
      const double wg = c2 / (c2 + static_cast<double>(sample.tail<2>().squaredNorm()) / (beam * beam));
      const double hw = huber_weight(r_beam, k);
      term.energy = wg * hw * r_beam * r_beam * (2.0 - hw);
      if (H == nullptr) continue;
      Matrix26d d_pose;
      Eigen::Vector2d d_rho;
      warp_jacobians(cam, w, t, d_pose, d_rho);
      term.J.head<6>() =
          (sample.tail<2>().cast<double>().transpose() * d_pose - host_term * lamp.d_log_g_d_pose).transpose();
      term.J[6] = -host_term;
      term.J[7] = -1.0;
      term.W = wg * hw / (beam * beam);
      term.r = r;
    }
  };
  // ...then summed in point order, as one loop over the points would: part 0 sums the counts,
  // the energy, g and H's first four columns, part 1 H's last four (each entry of H gets the
  // same additions in the same order, so the sums are the same to the bit).
  auto sums = [&](int part) {
    for (const PointTerm& term : terms_) {
      if (part == 0) {
        projected += term.kind >= 1 ? 1 : 0;
        if (term.kind == 2) energy += cutoff * cutoff;
        if (term.kind == 3) {
          ++inliers;
          energy += term.energy;
          if (H != nullptr) *g += term.W * term.r * term.J;
        }
      }
      if (term.kind != 3 || H == nullptr) continue;
      const Vector8d WJ = term.W * term.J;
      for (int j = 4 * part; j < 4 * part + 4; ++j) H_local.col(j) += WJ * term.J[j];
    }
  };
  // Coarse levels hold too few points to be worth the hand-over.
  constexpr std::size_t kParallelPoints = 1024;
  if (points.size() >= kParallelPoints) {
    split_in_two(*helper_, points.size(), points.size() / 2, kParallelPoints, point_terms);
    helper_->run([&] { sums(0); }, [&] { sums(1); });
  } else {
    point_terms(0, points.size(), 0);
    sums(0);
    sums(1);
  }
  if (H != nullptr) {
    *H = H_local;
    (*H)(6, 6) += options_.affine_a_prior;
    (*H)(7, 7) += options_.affine_b_prior;
    (*g)(6) += options_.affine_a_prior * a;
    (*g)(7) += options_.affine_b_prior * b;
  }
  energy += options_.affine_a_prior * a * a + options_.affine_b_prior * b * b;
  return inliers;
}

TrackingEstimate CoarseTracker::track(const ImagePyramid& frame, double exposure, const SE3& T_frame_ref_guess,
                                      double a_guess, double b_guess, const std::vector<double>* abort_reference,
                                      double abort_factor) const {
  TrackingEstimate out;
  out.T_frame_ref = T_frame_ref_guess;
  out.affine_a = a_guess;
  out.affine_b = b_guess;
  if (!has_reference()) return out;
  const int levels = std::min(frame.levels(), static_cast<int>(levels_.size()));
  out.level_rms.assign(static_cast<std::size_t>(levels), 0.0);
  SE3 T = T_frame_ref_guess;
  double a = a_guess;
  double b = b_guess;
  for (int l = levels - 1; l >= 0; --l) {
    double cutoff = options_.outlier_threshold;
    Matrix8d H;
    Vector8d g;
    double energy = 0.0;
    int projected = 0;
    int inliers = accumulate(l, frame, exposure, T, a, b, cutoff, &H, &g, energy, projected);
    // Too few inliers at this level: widen the cutoff (a large motion, or a brightness jump).
    for (int widen = 0; widen < 2 && projected > 0 && inliers < 0.6 * projected; ++widen) {
      cutoff *= 2.0;
      inliers = accumulate(l, frame, exposure, T, a, b, cutoff, &H, &g, energy, projected);
    }
    double lambda = 1e-2;
    for (int it = 0; it < options_.iterations_per_level && inliers >= 8; ++it) {
      Matrix8d A = H;
      A.diagonal() *= 1.0 + lambda;
      const Vector8d dx = A.ldlt().solve(-g);
      if (!dx.allFinite()) break;
      const SE3 T_new = SE3::exp(dx.head<6>()) * T;
      const double a_new = a + dx[6];
      const double b_new = b + dx[7];
      Matrix8d H_new;
      Vector8d g_new;
      double energy_new = 0.0;
      int projected_new = 0;
      const int inliers_new =
          accumulate(l, frame, exposure, T_new, a_new, b_new, cutoff, &H_new, &g_new, energy_new, projected_new);
      // Compare mean energies: the set of projecting points may change with the step.
      const double mean_old = energy / std::max(1, projected);
      const double mean_new = energy_new / std::max(1, projected_new);
      if (mean_new < mean_old && inliers_new >= 8) {
        T = T_new;
        a = a_new;
        b = b_new;
        H = H_new;
        g = g_new;
        energy = energy_new;
        projected = projected_new;
        inliers = inliers_new;
        lambda = std::max(lambda * 0.5, 1e-4);
        if (dx.norm() < 1e-5) break;
      } else {
        lambda *= 4.0;
        if (lambda > 1e4) break;
      }
    }
    const double rms = std::sqrt(energy / std::max(1, projected));
    out.level_rms[static_cast<std::size_t>(l)] = rms;
    if (abort_reference != nullptr && l < static_cast<int>(abort_reference->size()) &&
        (*abort_reference)[static_cast<std::size_t>(l)] > 0.0 &&
        rms > abort_factor * (*abort_reference)[static_cast<std::size_t>(l)]) {
      out.T_frame_ref = T;
      out.rms = rms;
      return out;  // valid stays false
    }
    if (l == 0) {
      out.rms = rms;
      out.residual_count = inliers;
      out.inlier_fraction = projected > 0 ? static_cast<double>(inliers) / projected : 0.0;
    }
  }
  out.T_frame_ref = T;
  out.affine_a = a;
  out.affine_b = b;
  out.valid = out.residual_count >= 20;

  // Optical flow of the level-0 points, for the keyframe decision.
  const LevelCamera& cam = cameras_[0];
  const Eigen::Matrix3d R = T.rotation_matrix();
  const Eigen::Vector3d t = T.translation();
  double sum_t = 0.0;
  double sum_full = 0.0;
  int n = 0;
  for (const LevelPoint& p : levels_[0]) {
    Warp w_full;
    Warp w_t;
    const Eigen::Vector2d px(p.u, p.v);
    if (!warp_pixel(cam, R, t, px, p.inverse_depth, w_full) ||
        !warp_pixel(cam, Eigen::Matrix3d::Identity(), t, px, p.inverse_depth, w_t))
      continue;
    sum_full += (w_full.pixel - px).squaredNorm();
    sum_t += (w_t.pixel - px).squaredNorm();
    ++n;
  }
  out.flow_translation = n > 0 ? std::sqrt(sum_t / n) : 0.0;
  out.flow_full = n > 0 ? std::sqrt(sum_full / n) : 0.0;
  return out;
}

}  // namespace nirslam::odometry
