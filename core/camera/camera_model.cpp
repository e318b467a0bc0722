#include "nirslam/camera/camera_model.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include <Eigen/LU>

namespace nirslam {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Below this undistorted radius the radial models use their limits at r = 0: the closed forms
// divide by r (or r^3), and the terms they feed are O(r^2) there anyway.
constexpr double kTinyRadius = 1e-7;

// d(x, y)/dp for (x, y) = (X/Z, Y/Z).
Matrix23d normalise_jacobian(const Eigen::Vector3d& p) {
  const double inv_z = 1.0 / p.z();
  Matrix23d d_xy_d_p;
  d_xy_d_p << inv_z, 0.0, -p.x() * inv_z * inv_z,  //
      0.0, inv_z, -p.y() * inv_z * inv_z;
  return d_xy_d_p;
}

// For radially symmetric models m = g(r) (x, y): dm/d(x, y) = g I + (g'(r) / r) (x, y)(x, y)^T.
// `g_prime_over_r` is passed instead of g' because it has a finite limit at r = 0.
Eigen::Matrix2d radial_jacobian(const Eigen::Vector2d& xy, double g, double g_prime_over_r) {
  return g * Eigen::Matrix2d::Identity() + g_prime_over_r * xy * xy.transpose();
}

void require_finite(const Eigen::VectorXd& values, const char* what) {
  if (!values.allFinite()) throw std::invalid_argument(std::string(what) + " must be finite");
}

}  // namespace

std::string_view to_string(CameraModelType type) {
  switch (type) {
    case CameraModelType::Pinhole: return "Pinhole";
    case CameraModelType::RadTan: return "RadTan";
    case CameraModelType::Fov: return "FOV";
    case CameraModelType::Equidistant: return "EquiDistant";
  }
  return "unknown";
}

// ---------------------------------------------------------------------------------------------
// CameraModel

CameraModel::CameraModel(CameraModelType type, int width, int height,
                         const Eigen::Vector4d& fx_fy_cx_cy)
    : type_(type), width_(width), height_(height), intrinsics_(fx_fy_cx_cy) {
  if (width <= 0 || height <= 0)
    throw std::invalid_argument("image size must be positive, got " + std::to_string(width) + "x" +
                                std::to_string(height));
  require_finite(fx_fy_cx_cy, "intrinsics fx fy cx cy");
  if (!(fx_fy_cx_cy[0] > 0.0) || !(fx_fy_cx_cy[1] > 0.0))
    throw std::invalid_argument("focal lengths fx, fy must be positive");
}

Eigen::Matrix3d CameraModel::K() const {
  Eigen::Matrix3d k = Eigen::Matrix3d::Identity();
  k(0, 0) = fx();
  k(1, 1) = fy();
  k(0, 2) = cx();
  k(1, 2) = cy();
  return k;
}

std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& p_cam,
                                                    Matrix23d* d_pixel_d_point) const {
  if (!(p_cam.z() > 0.0) || !p_cam.allFinite()) return std::nullopt;
  Matrix23d dm_dp;
  const std::optional<Eigen::Vector2d> m =
      distort_point(p_cam, d_pixel_d_point != nullptr ? &dm_dp : nullptr);
  if (!m || !m->allFinite()) return std::nullopt;
  const Eigen::Vector2d pixel(fx() * m->x() + cx(), fy() * m->y() + cy());
  if (d_pixel_d_point != nullptr) {
    d_pixel_d_point->row(0) = fx() * dm_dp.row(0);
    d_pixel_d_point->row(1) = fy() * dm_dp.row(1);
  }
  return pixel;
}

std::optional<Eigen::Vector3d> CameraModel::unproject(const Eigen::Vector2d& pixel) const {
  if (!pixel.allFinite()) return std::nullopt;
  const Eigen::Vector2d m((pixel.x() - cx()) / fx(), (pixel.y() - cy()) / fy());
  const std::optional<Eigen::Vector2d> xy = undistort_normalised(m);
  if (!xy || !xy->allFinite()) return std::nullopt;
  return Eigen::Vector3d(xy->x(), xy->y(), 1.0);
}

bool CameraModel::contains(const Eigen::Vector2d& pixel, double border) const {
  return pixel.x() >= border && pixel.y() >= border && pixel.x() <= width_ - 1 - border &&
         pixel.y() <= height_ - 1 - border;
}

std::string CameraModel::describe() const {
  std::ostringstream out;
  out.precision(10);
  out << name() << ' ' << width_ << 'x' << height_ << " fx=" << fx() << " fy=" << fy()
      << " cx=" << cx() << " cy=" << cy();
  const Eigen::VectorXd d = distortion();
  if (d.size() > 0) {
    out << " dist=[";
    for (Eigen::Index i = 0; i < d.size(); ++i) out << (i > 0 ? " " : "") << d[i];
    out << ']';
  }
  return out.str();
}

// ---------------------------------------------------------------------------------------------
// PinholeCamera

PinholeCamera::PinholeCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy)
    : CameraModel(CameraModelType::Pinhole, width, height, fx_fy_cx_cy) {}

std::unique_ptr<CameraModel> PinholeCamera::clone() const {
  return std::make_unique<PinholeCamera>(*this);
}

std::optional<Eigen::Vector2d> PinholeCamera::distort_point(const Eigen::Vector3d& p_cam,
                                                            Matrix23d* dm_dp) const {
  if (dm_dp != nullptr) *dm_dp = normalise_jacobian(p_cam);
  return Eigen::Vector2d(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
}

std::optional<Eigen::Vector2d> PinholeCamera::undistort_normalised(const Eigen::Vector2d& m) const {
  return m;
}

// ---------------------------------------------------------------------------------------------
// RadTanCamera

namespace {

// Smallest s = r^2 > 0 where d/dr [r (1 + k1 r^2 + k2 r^4)] = 1 + 3 k1 s + 5 k2 s^2 reaches zero.
double radtan_monotonic_limit(double k1, double k2) {
  if (k2 == 0.0) return k1 < 0.0 ? -1.0 / (3.0 * k1) : kInfinity;
  const double discriminant = 9.0 * k1 * k1 - 20.0 * k2;
  if (discriminant < 0.0) return kInfinity;  // the derivative never vanishes: 1 at s = 0, no root
  const double sqrt_d = std::sqrt(discriminant);
  double smallest = kInfinity;
  for (const double root : {(-3.0 * k1 - sqrt_d) / (10.0 * k2), (-3.0 * k1 + sqrt_d) / (10.0 * k2)})
    if (root > 0.0 && root < smallest) smallest = root;
  return smallest;
}

}  // namespace

RadTanCamera::RadTanCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy,
                           const Eigen::Vector4d& k1_k2_p1_p2)
    : CameraModel(CameraModelType::RadTan, width, height, fx_fy_cx_cy),
      coefficients_(k1_k2_p1_p2),
      max_radius_squared_(0.0) {
  require_finite(k1_k2_p1_p2, "radial-tangential coefficients k1 k2 p1 p2");
  max_radius_squared_ = radtan_monotonic_limit(k1(), k2());
}

std::unique_ptr<CameraModel> RadTanCamera::clone() const {
  return std::make_unique<RadTanCamera>(*this);
}

Eigen::Vector2d RadTanCamera::distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* dm_dxy) const {
  const double x = xy.x();
  const double y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1() + r2 * k2());
  const Eigen::Vector2d m(x * radial + 2.0 * p1() * x * y + p2() * (r2 + 2.0 * x * x),
                          y * radial + p1() * (r2 + 2.0 * y * y) + 2.0 * p2() * x * y);
  if (dm_dxy != nullptr) {
    // d radial / dx = 2 x (k1 + 2 k2 r^2), likewise for y.
    const double d_radial_d_r2 = k1() + 2.0 * k2() * r2;
    (*dm_dxy)(0, 0) = radial + 2.0 * x * x * d_radial_d_r2 + 2.0 * p1() * y + 6.0 * p2() * x;
    (*dm_dxy)(0, 1) = 2.0 * x * y * d_radial_d_r2 + 2.0 * p1() * x + 2.0 * p2() * y;
    (*dm_dxy)(1, 0) = 2.0 * x * y * d_radial_d_r2 + 2.0 * p1() * x + 2.0 * p2() * y;
    (*dm_dxy)(1, 1) = radial + 2.0 * y * y * d_radial_d_r2 + 6.0 * p1() * y + 2.0 * p2() * x;
  }
  return m;
}

std::optional<Eigen::Vector2d> RadTanCamera::distort_point(const Eigen::Vector3d& p_cam,
                                                           Matrix23d* dm_dp) const {
  const Eigen::Vector2d xy(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
  if (!(xy.squaredNorm() < max_radius_squared_)) return std::nullopt;
  if (dm_dp == nullptr) return distort(xy);
  Eigen::Matrix2d dm_dxy;
  const Eigen::Vector2d m = distort(xy, &dm_dxy);
  *dm_dp = dm_dxy * normalise_jacobian(p_cam);
  return m;
}

std::optional<Eigen::Vector2d> RadTanCamera::undistort_normalised(const Eigen::Vector2d& m) const {
  // Newton's method on distort(xy) = m from xy = m, with step halving so that the residual never
  // grows (strong barrel distortion near the image corners overshoots a plain Newton step).
  constexpr int kMaxIterations = 30;
  constexpr double kConverged = 1e-13;  // normalised units: ~1e-10 px at f = 1000
  Eigen::Vector2d xy = m;
  Eigen::Matrix2d J;
  Eigen::Vector2d residual = distort(xy, &J) - m;
  for (int iteration = 0; iteration < kMaxIterations && residual.norm() > kConverged; ++iteration) {
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-12)) return std::nullopt;  // at a fold: no unique inverse
    Eigen::Vector2d step = -J.inverse() * residual;
    bool improved = false;
    for (int halving = 0; halving < 20; ++halving, step *= 0.5) {
      Eigen::Matrix2d J_candidate;
      const Eigen::Vector2d candidate = xy + step;
      const Eigen::Vector2d candidate_residual = distort(candidate, &J_candidate) - m;
      if (candidate_residual.norm() < residual.norm()) {
        xy = candidate;
        residual = candidate_residual;
        J = J_candidate;
        improved = true;
        break;
      }
    }
    if (!improved) break;
  }
  // 1e-9 normalised is ~1e-6 px: anything worse is a failure to invert, not rounding.
  if (!(residual.norm() < 1e-9)) return std::nullopt;
  if (!(xy.squaredNorm() < max_radius_squared_)) return std::nullopt;  // the folded branch
  return xy;
}

// ---------------------------------------------------------------------------------------------
// FovCamera

FovCamera::FovCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy, double omega)
    : CameraModel(CameraModelType::Fov, width, height, fx_fy_cx_cy),
      omega_(omega),
      two_tan_half_omega_(2.0 * std::tan(omega / 2.0)) {
  if (!(omega > 0.0 && omega < std::numbers::pi))
    throw std::invalid_argument("FOV parameter omega must be in (0, pi) radians, got " +
                                std::to_string(omega));
}

Eigen::VectorXd FovCamera::distortion() const {
  Eigen::VectorXd d(1);
  d[0] = omega_;
  return d;
}

std::unique_ptr<CameraModel> FovCamera::clone() const { return std::make_unique<FovCamera>(*this); }

std::optional<Eigen::Vector2d> FovCamera::distort_point(const Eigen::Vector3d& p_cam,
                                                        Matrix23d* dm_dp) const {
  const Eigen::Vector2d xy(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
  const double r = xy.norm();
  const double t = two_tan_half_omega_;
  // g(r) = atan(r t) / (omega r); its limit at r = 0 is t / omega (DSO uses 1 there, a
  // discontinuity at the single principal point that we do not copy).
  double g = 0.0;
  double g_prime_over_r = 0.0;
  if (r < kTinyRadius) {
    g = t / omega_;
    g_prime_over_r = -2.0 / 3.0 * t * t * t / omega_;
  } else {
    const double atan_rt = std::atan(r * t);
    g = atan_rt / (omega_ * r);
    g_prime_over_r = (r * t / (1.0 + r * r * t * t) - atan_rt) / (omega_ * r * r * r);
  }
  if (dm_dp != nullptr) *dm_dp = radial_jacobian(xy, g, g_prime_over_r) * normalise_jacobian(p_cam);
  return Eigen::Vector2d(g * xy);
}

std::optional<Eigen::Vector2d> FovCamera::undistort_normalised(const Eigen::Vector2d& m) const {
  const double r_d = m.norm();
  // r_u = tan(r_d omega) / t: rays at or beyond 90 degrees have no point on z = 1.
  if (!(r_d * omega_ < std::numbers::pi / 2.0)) return std::nullopt;
  if (r_d < kTinyRadius) return Eigen::Vector2d(m * (omega_ / two_tan_half_omega_));
  const double r_u = std::tan(r_d * omega_) / two_tan_half_omega_;
  return Eigen::Vector2d(m * (r_u / r_d));
}

// ---------------------------------------------------------------------------------------------
// EquidistantCamera

EquidistantCamera::EquidistantCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy,
                                     const Eigen::Vector4d& k1_k2_k3_k4)
    : CameraModel(CameraModelType::Equidistant, width, height, fx_fy_cx_cy),
      coefficients_(k1_k2_k3_k4),
      max_theta_(std::numbers::pi / 2.0) {
  require_finite(k1_k2_k3_k4, "equidistant coefficients k1 k2 k3 k4");
  // First angle where d theta_d / d theta = 1 + 3 k1 t^2 + 5 k2 t^4 + 7 k3 t^6 + 9 k4 t^8
  // reaches zero: a scan at 1 mrad finds the bracket, bisection the root.
  constexpr int kSteps = 1571;
  const double step = (std::numbers::pi / 2.0) / kSteps;
  for (int i = 1; i <= kSteps; ++i) {
    double slope = 0.0;
    distort_angle(i * step, &slope);
    if (slope <= 0.0) {
      double lo = (i - 1) * step;
      double hi = i * step;
      for (int k = 0; k < 60; ++k) {
        const double mid = 0.5 * (lo + hi);
        distort_angle(mid, &slope);
        (slope > 0.0 ? lo : hi) = mid;
      }
      max_theta_ = lo;
      break;
    }
  }
}

std::unique_ptr<CameraModel> EquidistantCamera::clone() const {
  return std::make_unique<EquidistantCamera>(*this);
}

double EquidistantCamera::distort_angle(double theta, double* d_thetad_d_theta) const {
  const double t2 = theta * theta;
  const double k1 = coefficients_[0], k2 = coefficients_[1], k3 = coefficients_[2],
               k4 = coefficients_[3];
  // Horner in theta^2.
  const double poly = 1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)));
  if (d_thetad_d_theta != nullptr)
    *d_thetad_d_theta = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
  return theta * poly;
}

std::optional<Eigen::Vector2d> EquidistantCamera::distort_point(const Eigen::Vector3d& p_cam,
                                                                Matrix23d* dm_dp) const {
  const Eigen::Vector2d xy(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
  const double r = xy.norm();
  const double theta = std::atan(r);
  if (!(theta < max_theta_)) return std::nullopt;
  // m = g(r) (x, y) with g(r) = theta_d(atan r) / r; limit 1 at r = 0.
  double g = 0.0;
  double g_prime_over_r = 0.0;
  if (r < kTinyRadius) {
    g = 1.0;
    g_prime_over_r = 2.0 * (coefficients_[0] - 1.0 / 3.0);
  } else {
    double d_thetad_d_theta = 0.0;
    const double theta_d = distort_angle(theta, &d_thetad_d_theta);
    g = theta_d / r;
    // g' = (theta_d'(theta) * d theta/dr * r - theta_d) / r^2, d theta/dr = 1 / (1 + r^2).
    g_prime_over_r = (d_thetad_d_theta * r / (1.0 + r * r) - theta_d) / (r * r * r);
  }
  if (dm_dp != nullptr) *dm_dp = radial_jacobian(xy, g, g_prime_over_r) * normalise_jacobian(p_cam);
  return Eigen::Vector2d(g * xy);
}

std::optional<Eigen::Vector2d> EquidistantCamera::undistort_normalised(
    const Eigen::Vector2d& m) const {
  const double theta_d = m.norm();
  if (theta_d < kTinyRadius) return m;  // theta_d ~ theta ~ tan(theta) near the axis
  if (!(theta_d < distort_angle(max_theta_))) return std::nullopt;
  // theta_d(theta) increases on [0, max_theta]: Newton safeguarded by bisection always converges.
  double lo = 0.0;
  double hi = max_theta_;
  double theta = theta_d < hi ? theta_d : 0.5 * hi;
  for (int iteration = 0; iteration < 60; ++iteration) {
    double slope = 0.0;
    const double f = distort_angle(theta, &slope) - theta_d;
    if (std::abs(f) < 1e-15) break;
    (f > 0.0 ? hi : lo) = theta;
    double next = theta - f / slope;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    theta = next;
  }
  if (!(std::abs(distort_angle(theta) - theta_d) < 1e-12) || !(theta < max_theta_))
    return std::nullopt;
  return Eigen::Vector2d(m * (std::tan(theta) / theta_d));
}

}  // namespace nirslam
