#include "ui/gl/orbit_camera.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace nirslam::ui::gl {
namespace {
constexpr float kMaxPitch = 1.5607f;  // just short of straight down: the view's up stays defined
}

void OrbitCamera::ground_axes(Eigen::Vector3f& a, Eigen::Vector3f& b) const {
  const Eigen::Vector3f u = up.normalized();
  // Any vector not parallel to up gives the plane; x unless up is (close to) x.
  const Eigen::Vector3f seed = std::abs(u.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
  a = (seed - seed.dot(u) * u).normalized();
  b = u.cross(a);
}

Eigen::Vector3f OrbitCamera::eye() const {
  Eigen::Vector3f a;
  Eigen::Vector3f b;
  ground_axes(a, b);
  const Eigen::Vector3f direction =
      std::cos(pitch) * (std::cos(yaw) * a + std::sin(yaw) * b) + std::sin(pitch) * up.normalized();
  return target + distance * direction;
}

Eigen::Matrix4f OrbitCamera::view() const {
  const Eigen::Vector3f e = eye();
  const Eigen::Vector3f forward = (target - e).normalized();
  const Eigen::Vector3f right = forward.cross(up.normalized()).normalized();
  const Eigen::Vector3f camera_up = right.cross(forward);
  Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
  m.block<1, 3>(0, 0) = right.transpose();
  m.block<1, 3>(1, 0) = camera_up.transpose();
  m.block<1, 3>(2, 0) = -forward.transpose();
  m(0, 3) = -right.dot(e);
  m(1, 3) = -camera_up.dot(e);
  m(2, 3) = forward.dot(e);
  return m;
}

Eigen::Matrix4f OrbitCamera::projection(float aspect) const {
  const float near = std::max(1e-4f, 0.01f * distance);
  const float far = std::max(near * 10.0f, 200.0f * distance);
  const float f = 1.0f / std::tan(0.5f * vertical_fov);
  Eigen::Matrix4f p = Eigen::Matrix4f::Zero();
  p(0, 0) = f / std::max(aspect, 1e-3f);
  p(1, 1) = f;
  p(2, 2) = (far + near) / (near - far);
  p(2, 3) = 2.0f * far * near / (near - far);
  p(3, 2) = -1.0f;
  return p;
}

void OrbitCamera::orbit(float dx, float dy) {
  yaw -= 0.008f * dx;
  pitch = std::clamp(pitch + 0.008f * dy, -kMaxPitch, kMaxPitch);
}

void OrbitCamera::pan(float dx, float dy, float viewport_height) {
  const Eigen::Vector3f forward = (target - eye()).normalized();
  const Eigen::Vector3f right = forward.cross(up.normalized()).normalized();
  const Eigen::Vector3f camera_up = right.cross(forward);
  // One screen pixel at the target's distance, so the point under the cursor follows it.
  const float metres_per_pixel = 2.0f * distance * std::tan(0.5f * vertical_fov) / std::max(viewport_height, 1.0f);
  target += metres_per_pixel * (-dx * right + dy * camera_up);
}

void OrbitCamera::zoom(float wheel_steps) {
  distance = std::clamp(distance * std::pow(0.85f, wheel_steps), 1e-3f, 1e5f);
}

void OrbitCamera::frame(const Eigen::Vector3f& centre, float radius) {
  target = centre;
  distance = std::max(1e-2f, radius) / std::sin(0.5f * vertical_fov) * 1.05f;
}

void OrbitCamera::top_view() { pitch = kMaxPitch; }

}  // namespace nirslam::ui::gl
