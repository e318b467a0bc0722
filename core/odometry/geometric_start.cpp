#include "nirslam/odometry/geometric_start.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include <Eigen/Cholesky>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "nirslam/common/huber.hpp"
#include "nirslam/photometric/photometric_tracker.hpp"

namespace nirslam::odometry {

namespace {

constexpr int kTrackLevels = 3;

PhotometricTrackerOptions track_options(const GeometricStartOptions& options) {
  PhotometricTrackerOptions o;
  o.pyramid_levels = kTrackLevels;
  o.max_residual_rms = options.max_track_residual;
  return o;
}

Eigen::Vector3d triangulate(const LevelCamera& cam, const SE3& T_a, const Eigen::Vector2d& pa, const SE3& T_b,
                            const Eigen::Vector2d& pb, bool& ok) {
  // Linear triangulation (DLT) in normalised coordinates.
  const Eigen::Vector3d xa = cam.unproject(pa), xb = cam.unproject(pb);
  Eigen::Matrix<double, 3, 4> Pa, Pb;
  Pa << T_a.rotation_matrix(), T_a.translation();
  Pb << T_b.rotation_matrix(), T_b.translation();
  Eigen::Matrix4d A;
  A.row(0) = xa.x() * Pa.row(2) - Pa.row(0);
  A.row(1) = xa.y() * Pa.row(2) - Pa.row(1);
  A.row(2) = xb.x() * Pb.row(2) - Pb.row(0);
  A.row(3) = xb.y() * Pb.row(2) - Pb.row(1);
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);
  ok = std::abs(h[3]) > 1e-12;
  if (!ok) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d X = h.head<3>() / h[3];
  ok = (T_a * X).z() > 1e-3 && (T_b * X).z() > 1e-3;
  return X;
}

SE3 pose_from_cv(const cv::Mat& R, const cv::Mat& t) {
  Eigen::Matrix3d Re;
  Eigen::Vector3d te;
  for (int r = 0; r < 3; ++r) {
    te[r] = t.at<double>(r);
    for (int c = 0; c < 3; ++c) Re(r, c) = R.at<double>(r, c);
  }
  return {Re, te};
}

}  // namespace

bool reprojection_jacobians(const LevelCamera& cam, const SE3& T_frame_first, const Eigen::Vector3d& point_first,
                            const Eigen::Vector2d& pixel, Eigen::Vector2d& residual,
                            Eigen::Matrix<double, 2, 6>& d_pose, Eigen::Matrix<double, 2, 3>& d_point) {
  const Eigen::Vector3d p = T_frame_first * point_first;
  if (p.z() < 1e-6) return false;
  const double iz = 1.0 / p.z();
  residual = cam.project(p) - pixel;
  Eigen::Matrix<double, 2, 3> d_proj;
  d_proj << cam.fx * iz, 0.0, -cam.fx * p.x() * iz * iz, 0.0, cam.fy * iz, -cam.fy * p.y() * iz * iz;
  // exp(xi) T X = p + upsilon + omega x p: d p / d xi = [I, -[p]x].
  d_pose.leftCols<3>() = d_proj;
  d_pose.rightCols<3>() = -d_proj * skew(p);
  d_point = d_proj * T_frame_first.rotation_matrix();
  return true;
}

BundleResult adjust_bundle(const LevelCamera& cam, std::vector<SE3>& T_frame_first, std::vector<Eigen::Vector3d>& points,
                           const std::vector<BundleObservation>& observations, double huber_px, int iterations) {
  const int frames = static_cast<int>(T_frame_first.size());
  const int n = 6 * (frames - 1);
  BundleResult out;
  if (frames < 2 || n == 0) return out;

  auto energy_of = [&](const std::vector<SE3>& T, const std::vector<Eigen::Vector3d>& X) {
    double e = 0.0;
    for (const auto& o : observations) {
      const Eigen::Vector3d p = T[static_cast<std::size_t>(o.frame)] * X[static_cast<std::size_t>(o.point)];
      if (p.z() < 1e-6) {
        e += 2.0 * huber_px * 50.0;  // behind the camera: a large outlier cost
        continue;
      }
      e += twice_huber_loss((cam.project(p) - o.pixel).norm(), huber_px);
    }
    return e;
  };

  std::vector<Eigen::Matrix3d> H_xx(points.size());
  std::vector<Eigen::Vector3d> b_x(points.size());
  std::vector<std::vector<std::pair<int, Eigen::Matrix<double, 6, 3>>>> H_cx(points.size());
  Eigen::MatrixXd H(n, n);
  Eigen::VectorXd b(n);
  double lambda = 1e-4;
  double energy = energy_of(T_frame_first, points);
  for (int it = 0; it < iterations; ++it) {
    out.iterations = it + 1;
    H.setZero();
    b.setZero();
    for (std::size_t i = 0; i < points.size(); ++i) {
      H_xx[i].setZero();
      b_x[i].setZero();
      H_cx[i].clear();
    }
    for (const auto& o : observations) {
      Eigen::Vector2d r;
      Eigen::Matrix<double, 2, 6> Jc;
      Eigen::Matrix<double, 2, 3> Jx;
      const auto pi = static_cast<std::size_t>(o.point);
      if (!reprojection_jacobians(cam, T_frame_first[static_cast<std::size_t>(o.frame)], points[pi], o.pixel, r, Jc, Jx))
        continue;
      const double w = huber_weight(r.norm(), huber_px);
      H_xx[pi] += w * Jx.transpose() * Jx;
      b_x[pi] += w * Jx.transpose() * r;
      if (o.frame == 0) continue;
      const int c = 6 * (o.frame - 1);
      H.block<6, 6>(c, c) += w * Jc.transpose() * Jc;
      b.segment<6>(c) += w * Jc.transpose() * r;
      const Eigen::Matrix<double, 6, 3> Hcx = w * Jc.transpose() * Jx;
      auto& row = H_cx[pi];
      auto found = std::find_if(row.begin(), row.end(), [&](const auto& e) { return e.first == o.frame; });
      if (found == row.end())
        row.emplace_back(o.frame, Hcx);
      else
        found->second += Hcx;
    }
    // Damped Schur complement over the points.
    Eigen::MatrixXd S = H;
    Eigen::VectorXd s = b;
    for (int d = 0; d < n; ++d) S(d, d) *= 1.0 + lambda;
    std::vector<Eigen::Matrix3d> H_xx_inv(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      Eigen::Matrix3d Hd = H_xx[i];
      Hd.diagonal() *= 1.0 + lambda;
      Hd.diagonal().array() += 1e-9;
      H_xx_inv[i] = Hd.inverse();
      for (const auto& [fa, Ha] : H_cx[i]) {
        const int ca = 6 * (fa - 1);
        const Eigen::Matrix<double, 6, 3> HaHinv = Ha * H_xx_inv[i];
        s.segment<6>(ca) -= HaHinv * b_x[i];
        for (const auto& [fb, Hb] : H_cx[i]) S.block<6, 6>(ca, 6 * (fb - 1)) -= HaHinv * Hb.transpose();
      }
    }
    const Eigen::VectorXd dc = -S.ldlt().solve(s);
    std::vector<SE3> T_new = T_frame_first;
    for (int f = 1; f < frames; ++f)
      T_new[static_cast<std::size_t>(f)] = SE3::exp(dc.segment<6>(6 * (f - 1))) * T_frame_first[static_cast<std::size_t>(f)];
    std::vector<Eigen::Vector3d> X_new = points;
    for (std::size_t i = 0; i < points.size(); ++i) {
      Eigen::Vector3d rhs = b_x[i];
      for (const auto& [fa, Ha] : H_cx[i]) rhs += Ha.transpose() * dc.segment<6>(6 * (fa - 1));
      X_new[i] -= H_xx_inv[i] * rhs;
    }
    const double e_new = energy_of(T_new, X_new);
    if (std::isfinite(e_new) && e_new < energy) {
      const bool converged = energy - e_new < 1e-6 * energy;
      T_frame_first = std::move(T_new);
      points = std::move(X_new);
      energy = e_new;
      lambda = std::max(1e-7, lambda * 0.3);
      if (converged) break;
    } else {
      lambda *= 10.0;
      if (lambda > 1e6) break;
    }
  }
  double sum = 0.0;
  for (const auto& o : observations) {
    const Eigen::Vector3d p = T_frame_first[static_cast<std::size_t>(o.frame)] * points[static_cast<std::size_t>(o.point)];
    if (p.z() < 1e-6) continue;
    const double r = (cam.project(p) - o.pixel).norm();
    if (r > 3.0 * huber_px) continue;
    sum += r * r;
    ++out.inlier_observations;
  }
  out.rms_px = out.inlier_observations > 0 ? std::sqrt(sum / out.inlier_observations) : 0.0;
  return out;
}

GeometricStart::GeometricStart(const LevelCamera& camera, const GeometricStartOptions& options)
    : camera_(camera), options_(options) {}

void GeometricStart::set_first(const cv::Mat& image) {
  previous_pyramid_ = build_intensity_pyramid(image, 8, kTrackLevels);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(previous_pyramid_[0], corners, options_.max_corners, options_.corner_quality,
                          options_.min_corner_distance_px);
  positions_.assign(1, {});
  alive_.assign(1, {});
  for (const auto& c : corners) {
    positions_[0].emplace_back(c.x, c.y);
    alive_[0].push_back(1);
  }
}

void GeometricStart::add_frame(const cv::Mat& image) {
  if (positions_.empty()) return;
  std::vector<cv::Mat> pyramid = build_intensity_pyramid(image, 8, kTrackLevels);
  const PhotometricTrackerOptions o = track_options(options_);
  const auto& last = positions_.back();
  const auto& last_alive = alive_.back();
  std::vector<Eigen::Vector2d> next(last.size(), Eigen::Vector2d::Zero());
  std::vector<char> next_alive(last.size(), 0);
  for (std::size_t i = 0; i < last.size(); ++i) {
    if (!last_alive[i]) continue;
    const auto forward = track_patch(previous_pyramid_, pyramid, last[i], last[i], o);
    if (!forward || forward->residual_rms > o.max_residual_rms) continue;
    const auto backward = track_patch(pyramid, previous_pyramid_, forward->position, last[i], o);
    if (!backward || (backward->position - last[i]).norm() > options_.max_forward_backward_px) continue;
    if (!camera_.inside(forward->position.x(), forward->position.y(), 2.0)) continue;
    next[i] = forward->position;
    next_alive[i] = 1;
  }
  positions_.push_back(std::move(next));
  alive_.push_back(std::move(next_alive));
  previous_pyramid_ = std::move(pyramid);
}

GeometricStartResult GeometricStart::solve() const {
  GeometricStartResult out;
  const int K = frames();
  if (K < 2) {
    out.reason = "too few frames";
    return out;
  }
  const std::size_t tracks = positions_[0].size();
  // A track's length: the frames it was followed into without a break.
  std::vector<int> length(tracks, 0);
  for (std::size_t i = 0; i < tracks; ++i)
    for (int k = 1; k <= K && alive_[static_cast<std::size_t>(k)][i]; ++k) length[i] = k;

  std::vector<cv::Point2f> a, b;
  std::vector<std::size_t> index;
  for (std::size_t i = 0; i < tracks; ++i) {
    if (length[i] < K) continue;
    const auto& p0 = positions_[0][i];
    const auto& pk = positions_[static_cast<std::size_t>(K)][i];
    a.emplace_back(static_cast<float>(p0.x()), static_cast<float>(p0.y()));
    b.emplace_back(static_cast<float>(pk.x()), static_cast<float>(pk.y()));
    index.push_back(i);
  }
  out.tracks_at_end = static_cast<int>(a.size());
  if (out.tracks_at_end < options_.min_inliers) {
    out.reason = std::to_string(out.tracks_at_end) + " tracks reach frame " + std::to_string(K);
    return out;
  }
  const cv::Mat K_cv = (cv::Mat_<double>(3, 3) << camera_.fx, 0, camera_.cx, 0, camera_.fy, camera_.cy, 0, 0, 1);
  cv::Mat mask;
  const cv::Mat E = cv::findEssentialMat(a, b, K_cv, cv::RANSAC, 0.999, options_.ransac_threshold_px, mask);
  if (E.rows != 3 || E.cols != 3) {
    out.reason = "no essential matrix";
    return out;
  }
  cv::Mat R, t;
  out.inliers = cv::recoverPose(E, a, b, K_cv, R, t, mask);
  if (out.inliers < options_.min_inliers) {
    out.reason = std::to_string(out.inliers) + " essential-matrix inliers of " + std::to_string(a.size());
    return out;
  }
  std::vector<SE3> T(static_cast<std::size_t>(K + 1));
  T[static_cast<std::size_t>(K)] = pose_from_cv(R, t);

  // Points: the essential matrix's inliers from the first and last frame.
  std::vector<Eigen::Vector3d> X;
  std::vector<int> point_of(tracks, -1);
  for (std::size_t j = 0; j < index.size(); ++j) {
    if (!mask.at<unsigned char>(static_cast<int>(j))) continue;
    bool ok = false;
    const Eigen::Vector3d p = triangulate(camera_, T[0], positions_[0][index[j]], T[static_cast<std::size_t>(K)],
                                          positions_[static_cast<std::size_t>(K)][index[j]], ok);
    if (!ok) continue;
    point_of[index[j]] = static_cast<int>(X.size());
    X.push_back(p);
  }
  // The frames between by PnP on those points.
  for (int k = 1; k < K; ++k) {
    std::vector<cv::Point3f> object;
    std::vector<cv::Point2f> image;
    for (std::size_t i = 0; i < tracks; ++i) {
      if (point_of[i] < 0) continue;
      const auto& p = X[static_cast<std::size_t>(point_of[i])];
      const auto& q = positions_[static_cast<std::size_t>(k)][i];
      object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
      image.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
    }
    cv::Mat rvec, tvec;
    if (object.size() < 6 || !cv::solvePnP(object, image, K_cv, cv::Mat(), rvec, tvec, false, cv::SOLVEPNP_EPNP)) {
      out.reason = "PnP failed on frame " + std::to_string(k);
      return out;
    }
    cv::Mat Rk;
    cv::Rodrigues(rvec, Rk);
    T[static_cast<std::size_t>(k)] = pose_from_cv(Rk, tvec);
  }
  // The shorter tracks too (seen in min_track_frames or more), from their first and last frame.
  for (std::size_t i = 0; i < tracks; ++i) {
    if (point_of[i] >= 0 || length[i] < options_.min_track_frames) continue;
    bool ok = false;
    const Eigen::Vector3d p =
        triangulate(camera_, T[0], positions_[0][i], T[static_cast<std::size_t>(length[i])],
                    positions_[static_cast<std::size_t>(length[i])][i], ok);
    if (!ok) continue;
    point_of[i] = static_cast<int>(X.size());
    X.push_back(p);
  }
  std::vector<BundleObservation> observations;
  for (std::size_t i = 0; i < tracks; ++i) {
    if (point_of[i] < 0) continue;
    for (int k = 0; k <= length[i]; ++k)
      observations.push_back({k, point_of[i], positions_[static_cast<std::size_t>(k)][i]});
  }
  const BundleResult bundle = adjust_bundle(camera_, T, X, observations, options_.huber_px, options_.iterations);
  out.points = static_cast<int>(X.size());
  out.rms_px = bundle.rms_px;
  if (!(bundle.rms_px <= options_.max_rms_px)) {
    out.reason = "bundle adjustment rms " + std::to_string(bundle.rms_px) + " px";
    return out;
  }
  // Under a rotation alone the direction is any: the flow the translation adds in the last frame.
  const SE3& T_last = T[static_cast<std::size_t>(K)];
  double parallax_sum = 0.0;
  int parallax_count = 0;
  for (std::size_t i = 0; i < tracks; ++i) {
    if (point_of[i] < 0 || length[i] < K) continue;
    const Eigen::Vector3d rotated = T_last.rotation_matrix() * X[static_cast<std::size_t>(point_of[i])];
    const Eigen::Vector3d moved = rotated + T_last.translation();
    if (rotated.z() < 1e-6 || moved.z() < 1e-6) continue;
    parallax_sum += (camera_.project(moved) - camera_.project(rotated)).squaredNorm();
    ++parallax_count;
  }
  out.parallax_px = parallax_count > 0 ? std::sqrt(parallax_sum / parallax_count) : 0.0;
  if (!(out.parallax_px >= options_.min_parallax_px)) {
    out.reason = "translational parallax " + std::to_string(out.parallax_px) + " px by frame " + std::to_string(K);
    return out;
  }
  // The direct initialiser's gauge: mean inverse depth 1 in the first frame.
  double inverse_depth_sum = 0.0;
  int inverse_depth_count = 0;
  for (const auto& p : X)
    if (p.z() > 1e-6) {
      inverse_depth_sum += 1.0 / p.z();
      ++inverse_depth_count;
    }
  if (inverse_depth_count == 0) {
    out.reason = "no point in front of the first frame";
    return out;
  }
  const double scale = inverse_depth_sum / inverse_depth_count;  // depths * scale: mean inverse depth 1
  for (auto& Tk : T) Tk = SE3(Tk.unit_quaternion(), Tk.translation() * scale);
  out.T_frame_first = std::move(T);
  out.ok = true;
  const SE3& T_end = out.T_frame_first.back();
  const Eigen::Vector3d direction = -(T_end.rotation_matrix().transpose() * T_end.translation()).normalized();
  char summary[224];
  std::snprintf(summary, sizeof summary,
                "%d tracks over %d frames, %d inliers, %d points, %.2f px rms, parallax %.1f px, direction of "
                "travel (%.3f, %.3f, %.3f) in the first frame's axes",
                out.tracks_at_end, K, out.inliers, out.points, out.rms_px, out.parallax_px, direction.x(),
                direction.y(), direction.z());
  out.reason = summary;
  return out;
}

}  // namespace nirslam::odometry
