#pragma once

#include <Eigen/Core>

namespace nirslam::ui::gl {

// The 3-D view's camera: it looks at `target` from `distance` away, at `yaw` about the world's
// up axis and `pitch` above the ground plane (radians). `up` is the scene's up direction (for a
// monocular estimate, the first camera's -y; for a ground-truth-aligned one, the world's z).
class OrbitCamera {
public:
  Eigen::Vector3f target = Eigen::Vector3f::Zero();
  Eigen::Vector3f up = Eigen::Vector3f::UnitZ();
  float yaw = 0.6f;
  float pitch = 0.5f;
  float distance = 5.0f;
  float vertical_fov = 0.8f;  // radians

  Eigen::Vector3f eye() const;
  Eigen::Matrix4f view() const;                     // world -> eye (OpenGL: looking down -z)
  Eigen::Matrix4f projection(float aspect) const;   // perspective, near/far from the distance
  Eigen::Matrix4f view_projection(float aspect) const { return projection(aspect) * view(); }

  // Mouse gestures, in screen pixels of a viewport `viewport_height` tall.
  void orbit(float dx, float dy);
  void pan(float dx, float dy, float viewport_height);
  void zoom(float wheel_steps);
  // Frames an axis-aligned box (centre and radius) from the current direction.
  void frame(const Eigen::Vector3f& centre, float radius);
  // Straight down onto the ground plane.
  void top_view();

private:
  // Two unit vectors spanning the ground plane (perpendicular to up).
  void ground_axes(Eigen::Vector3f& a, Eigen::Vector3f& b) const;
};

}  // namespace nirslam::ui::gl
