#include "nirslam/sim/trajectory.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "layout.hpp"
#include "nirslam/common/text_fields.hpp"

namespace nirslam::sim {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kDegree = 5;
constexpr double kControlSpacing = 0.5;  // m

double deg(double degrees) { return degrees * kPi / 180.0; }

// A rounded rectangle: the points at distance r from the rectangle [-hx, hx] x [-hy, hy]
// (hy = 0 gives a stadium), counter-clockwise from (hx + r, 0), densely sampled.
std::vector<Eigen::Vector2d> rounded_rectangle(double hx, double hy, double r) {
  std::vector<Eigen::Vector2d> points;
  const double step = 0.01;
  auto line = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const int n = std::max(1, static_cast<int>((b - a).norm() / step));
    for (int i = 0; i < n; ++i) points.push_back(a + (b - a) * (static_cast<double>(i) / n));
  };
  auto arc = [&](const Eigen::Vector2d& c, double from) {
    const int n = std::max(1, static_cast<int>(0.5 * kPi * r / step));
    for (int i = 0; i < n; ++i) {
      const double a = from + 0.5 * kPi * static_cast<double>(i) / n;
      points.emplace_back(c.x() + r * std::cos(a), c.y() + r * std::sin(a));
    }
  };
  line({hx + r, 0.0}, {hx + r, hy});
  arc({hx, hy}, 0.0);
  line({hx, hy + r}, {-hx, hy + r});
  arc({-hx, hy}, 0.5 * kPi);
  line({-hx - r, hy}, {-hx - r, -hy});
  arc({-hx, -hy}, kPi);
  line({-hx, -hy - r}, {hx, -hy - r});
  arc({hx, -hy}, 1.5 * kPi);
  line({hx + r, -hy}, {hx + r, 0.0});
  // Start in the middle of the lower straight, heading +x (not in a turn).
  const auto start = std::min_element(points.begin(), points.end(), [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a - Eigen::Vector2d(0.0, -hy - r)).norm() < (b - Eigen::Vector2d(0.0, -hy - r)).norm();
  });
  std::rotate(points.begin(), start, points.end());
  return points;
}

std::vector<Eigen::Vector2d> ellipse(double a, double b) {
  std::vector<Eigen::Vector2d> points;
  const int n = 4000;
  for (int i = 0; i < n; ++i) {
    const double t = 2.0 * kPi * i / n;
    points.emplace_back(a * std::cos(t), b * std::sin(t));
  }
  return points;
}

// Points every `spacing` metres of arc length round a closed dense polyline.
std::vector<Eigen::Vector2d> resample_closed(const std::vector<Eigen::Vector2d>& dense, double spacing) {
  std::vector<double> cumulative{0.0};
  for (std::size_t i = 1; i <= dense.size(); ++i)
    cumulative.push_back(cumulative.back() + (dense[i % dense.size()] - dense[i - 1]).norm());
  const double length = cumulative.back();
  const int n = std::max(8, static_cast<int>(std::lround(length / spacing)));
  std::vector<Eigen::Vector2d> out;
  std::size_t j = 0;
  for (int k = 0; k < n; ++k) {
    const double s = length * k / n;
    while (j + 1 < cumulative.size() && cumulative[j + 1] < s) ++j;
    const double span = cumulative[j + 1] - cumulative[j];
    const double f = span > 0.0 ? (s - cumulative[j]) / span : 0.0;
    out.push_back(dense[j] + (dense[(j + 1) % dense.size()] - dense[j]) * f);
  }
  return out;
}

}  // namespace

std::string_view to_string(MotionKind kind) {
  switch (kind) {
    case MotionKind::Handheld: return "handheld";
    case MotionKind::Vehicle: return "vehicle";
    case MotionKind::Robot: return "robot";
    case MotionKind::Tripod: return "tripod";
  }
  return "unknown";
}

std::optional<MotionKind> parse_motion_kind(std::string_view name) {
  const std::string key = lowercase(name);
  if (key == "handheld" || key == "hand-held") return MotionKind::Handheld;
  if (key == "vehicle") return MotionKind::Vehicle;
  if (key == "robot") return MotionKind::Robot;
  if (key == "tripod" || key == "still") return MotionKind::Tripod;
  return std::nullopt;
}

Trajectory::Trajectory(std::vector<Eigen::Vector2d> control_points, double height, double speed_mps, MotionKind kind,
                       std::uint32_t seed)
    : control_(std::move(control_points)), height_(height), speed_(speed_mps), kind_(kind) {
  if (control_.size() < kDegree + 1) throw std::invalid_argument("trajectory: too few control points");
  if (!(speed_ > 0.0)) throw std::invalid_argument("trajectory: speed must be positive");
  // Length of the spline loop.
  const int steps = static_cast<int>(control_.size()) * 20;
  Eigen::Vector2d previous = spline(0.0);
  for (int i = 1; i <= steps; ++i) {
    const Eigen::Vector2d p = spline(static_cast<double>(control_.size()) * i / steps);
    length_ += (p - previous).norm();
    previous = p;
  }
  period_ = length_ / speed_;
  std::uint64_t state = seed * 0x9E3779B97F4A7C15ull + 17u;
  for (int i = 0; i < phase_.size(); ++i) {
    state += 0x9E3779B97F4A7C15ull;
    std::uint64_t z = state;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    phase_[i] = 2.0 * kPi * static_cast<double>(z >> 11) / 9007199254740992.0;
  }
}

Eigen::Vector2d Trajectory::spline(double u) const {
  // De Boor on the uniform periodic knots: on [i, i+1) the points P[i-5] .. P[i] act.
  const int n = static_cast<int>(control_.size());
  u = std::fmod(u, static_cast<double>(n));
  if (u < 0.0) u += n;
  const int i = std::min(static_cast<int>(std::floor(u)), n - 1);
  std::array<Eigen::Vector2d, kDegree + 1> d;
  for (int j = 0; j <= kDegree; ++j) d[static_cast<std::size_t>(j)] = control_[static_cast<std::size_t>(((i - kDegree + j) % n + n) % n)];
  for (int r = 1; r <= kDegree; ++r)
    for (int j = kDegree; j >= r; --j) {
      const double alpha = (u - (j + i - kDegree)) / static_cast<double>(kDegree + 1 - r);
      d[static_cast<std::size_t>(j)] = (1.0 - alpha) * d[static_cast<std::size_t>(j - 1)] + alpha * d[static_cast<std::size_t>(j)];
    }
  return d[kDegree];
}

Eigen::Vector3d Trajectory::position(double t) const {
  if (kind_ == MotionKind::Tripod) t = 0.0;
  const double u = t / period_ * static_cast<double>(control_.size());
  const Eigen::Vector2d p = spline(u);
  double z = height_;
  Eigen::Vector2d xy = p;
  if (kind_ == MotionKind::Handheld) {
    // Walking: a vertical bob at the step rate and a sideways sway at half of it.
    const double h = 1e-3;
    const Eigen::Vector2d tangent = (spline(u + h) - spline(u - h)).normalized();
    const Eigen::Vector2d side(-tangent.y(), tangent.x());
    z += 0.015 * std::sin(2.0 * kPi * 1.8 * t + phase_[0]);
    xy += side * 0.012 * std::sin(2.0 * kPi * 0.9 * t + phase_[1]);
  }
  return {xy.x(), xy.y(), z};
}

SE3 Trajectory::pose(double t) const {
  if (kind_ == MotionKind::Tripod) t = 0.0;
  const double u = t / period_ * static_cast<double>(control_.size());
  const double h = 1e-3;
  const Eigen::Vector2d velocity = spline(u + h) - spline(u - h);
  double yaw = std::atan2(velocity.y(), velocity.x());
  double pitch = 0.0, roll = 0.0;
  const auto wave = [&](double amplitude_deg, double hz, int k) {
    return deg(amplitude_deg) * std::sin(2.0 * kPi * hz * t + phase_[k]);
  };
  switch (kind_) {
    case MotionKind::Handheld:
      yaw += wave(12.0, 0.07, 2) + wave(5.0, 0.23, 3);
      pitch = deg(-5.0) + wave(4.0, 0.11, 4);
      roll = wave(2.0, 0.17, 5) + wave(0.3, 3.1, 6);
      break;
    case MotionKind::Vehicle:
      pitch = deg(-3.0) + wave(0.3, 1.7, 4);
      roll = wave(0.3, 2.3, 5);
      break;
    case MotionKind::Robot:
      pitch = deg(2.0) + wave(0.2, 2.9, 4);
      roll = wave(0.2, 3.7, 5);
      break;
    case MotionKind::Tripod:
      pitch = deg(-5.0);  // the handheld's view at its start, held
      break;
  }
  // Camera axes (x right, y down, z forward) for heading 0 along world +x, then roll about the
  // forward axis, pitch up, yaw about world z.
  Eigen::Matrix3d base;
  base.col(0) = Eigen::Vector3d(0.0, -1.0, 0.0);
  base.col(1) = Eigen::Vector3d(0.0, 0.0, -1.0);
  base.col(2) = Eigen::Vector3d(1.0, 0.0, 0.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                            Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                            Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()).toRotationMatrix() * base;
  return SE3(R, position(t));
}

Trajectory make_trajectory(SceneKind scene, MotionKind kind, std::uint32_t seed) {
  using namespace layout;
  std::vector<Eigen::Vector2d> dense;
  double floor = 0.0;
  // Speeds (m/s) for handheld, vehicle, robot.
  std::array<double, 3> speed{1.0, 2.0, 0.5};
  std::array<double, 3> height{1.5, 1.3, 0.4};
  switch (scene) {
    case SceneKind::Room:
      dense = ellipse(kRoomLoopA, kRoomLoopB);
      speed = {0.7, 0.6, 0.35};
      height = {1.5, 1.0, 0.35};
      break;
    case SceneKind::Outdoor:
      dense = rounded_rectangle(kBlockHalfX, kBlockHalfY, kStreetLoopOffset);
      speed = {1.3, 4.0, 0.8};
      height = {1.5, 1.5, 0.5};
      break;
    case SceneKind::Parking:
      dense = rounded_rectangle(kParkLoopHalfX, 0.0, kAisleY);
      speed = {1.2, 2.5, 0.6};
      height = {1.5, 1.3, 0.45};
      break;
    case SceneKind::Tunnel:
      dense = rounded_rectangle(kTunnelLoopHalfX, 0.0, kTunnelLoopHalfY);
      floor = kWalkwayZ;
      speed = {1.0, 1.2, 0.5};
      height = {1.45, 0.9, 0.45};
      break;
  }
  // A tripod stands where the handheld path starts, at its height.
  const auto k = kind == MotionKind::Tripod ? std::size_t{0} : static_cast<std::size_t>(kind);
  return Trajectory(resample_closed(dense, kControlSpacing), floor + height[k], speed[k], kind, seed);
}

std::vector<double> frame_times(const Trajectory& trajectory, std::int64_t count, double fps,
                                const std::optional<CaptureRule>& rule) {
  if (count < 0) throw std::invalid_argument("frame count must not be negative");
  std::vector<double> times;
  times.reserve(static_cast<std::size_t>(count));
  if (!rule) {
    if (!(fps > 0.0)) throw std::invalid_argument("frame rate must be positive");
    for (std::int64_t i = 0; i < count; ++i) times.push_back(static_cast<double>(i) / fps);
    return times;
  }
  if (!(rule->max_interval_s > 0.0) || !(rule->max_distance_m > 0.0))
    throw std::invalid_argument("capture rule: interval and distance must be positive");
  const double dt = std::min(rule->max_interval_s, 1e-3) / 4.0;
  double t = 0.0, last = 0.0, moved = 0.0;
  Eigen::Vector3d previous = trajectory.position(0.0);
  if (count > 0) times.push_back(0.0);
  while (static_cast<std::int64_t>(times.size()) < count) {
    t += dt;
    const Eigen::Vector3d p = trajectory.position(t);
    moved += (p - previous).norm();
    previous = p;
    if (t - last >= rule->max_interval_s - 1e-12 || moved >= rule->max_distance_m) {
      times.push_back(t);
      last = t;
      moved = 0.0;
    }
  }
  return times;
}

}  // namespace nirslam::sim
