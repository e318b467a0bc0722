#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <imgui.h>

#include "nirslam/worker/snapshot.hpp"
#include "ui/gl/framebuffer.hpp"
#include "ui/gl/orbit_camera.hpp"
#include "ui/gl/shader.hpp"
#include "ui/gl/vertex_batch.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// The 3-D view of the odometry: the estimated trajectory (coloured by time, or by its absolute
// error when ground truth is known), the ground truth beside it, the map points (active ones
// tinted, marginalised ones grey), keyframe frusta and the current camera, over a ground grid.
// Drawn with shaders/scene.{vert,frag} into an offscreen framebuffer with a depth buffer.
// Mouse: left drag orbits, right (or middle, or Shift + left) drag pans, the wheel zooms,
// double-click frames everything. Buttons: fit, top view, follow the camera.
class TrajectoryPanel {
public:
  // Loads scene.vert/.frag from `shader_dir`; throws gl::ShaderError naming the file. Needs a
  // current GL context, for this call and for the panel's whole life.
  explicit TrajectoryPanel(const std::filesystem::path& shader_dir);

  void draw(const Snapshot& snapshot);

  enum class Colouring { Time, Error };
  Colouring colouring = Colouring::Error;  // falls back to time when no error is known
  bool show_points = true;
  bool show_keyframes = true;
  bool show_ground_truth = true;
  bool follow = false;       // keep the current camera at the centre of the view
  float point_size = 2.0f;   // pixels

  // Frames everything on the next draw, and keeps framing it as the trajectory grows until the
  // operator moves the view.
  void fit_all();
  void top_view() { camera_.top_view(); }
  gl::OrbitCamera& camera() { return camera_; }

  // Geometry of the last draw, for hit tests and the screenshot tests.
  const ScreenRect& view_rect() const { return view_; }
  // The screen position of a world point with the last draw's camera; nullopt behind the camera.
  std::optional<ImVec2> project(const Eigen::Vector3f& world) const;
  bool colouring_by_error() const { return by_error_; }

private:
  void draw_tool_row(const TrajectoryView* view);
  void handle_input(bool hovered, bool active);
  void rebuild(const TrajectoryView& view);
  void render();
  struct RenderKey;
  void render_points_layer(const RenderKey& key);
  void draw_overlays(const TrajectoryView& view);

  gl::Program program_;
  GLint u_view_projection_ = -1;
  GLint u_point_size_ = -1;
  GLint u_round_points_ = -1;
  gl::Framebuffer target_;
  gl::OrbitCamera camera_;
  gl::VertexBatch points_{GL_POINTS};
  gl::VertexBatch lines_{GL_LINES};
  gl::VertexBatch markers_{GL_POINTS};  // pose dots, so a short path still shows
  std::shared_ptr<const std::vector<MapPointSample>> uploaded_points_;
  // What the offscreen target last showed. The worker publishes a new view with every processed
  // frame (20-30 Hz) and the UI draws at 60 Hz: between views, and while the camera is still, the
  // target is composited again without re-rendering 100k points on a software rasteriser.
  struct RenderKey {
    const TrajectoryView* view = nullptr;
    bool points = false;
    bool keyframes = false;
    bool ground_truth = false;
    Colouring colouring = Colouring::Time;
    float point_size = 0.0f;
    int target_w = 0;
    int target_h = 0;
    Eigen::Matrix4f view_projection = Eigen::Matrix4f::Zero();
    bool operator==(const RenderKey& o) const {
      return view == o.view && points == o.points && keyframes == o.keyframes && ground_truth == o.ground_truth &&
             colouring == o.colouring && point_size == o.point_size && target_w == o.target_w &&
             target_h == o.target_h && view_projection == o.view_projection;
    }
  };
  RenderKey rendered_;
  // The map points alone (colour and depth), re-rendered only when the points, the camera or
  // the size change (points change on keyframes): a new pose then costs a copy of this layer plus
  // the lines, not 100k point sprites.
  gl::Framebuffer points_layer_;
  RenderKey points_rendered_;
  std::shared_ptr<const std::vector<MapPointSample>> points_uploaded_for_layer_;
  // The sphere the camera was last fitted to: auto-framing refits only when the path leaves it,
  // so the camera (and the points layer) stay still while the path grows inside it.
  Eigen::Vector3f framed_centre_ = Eigen::Vector3f::Zero();
  float framed_radius_ = 0.0f;
  std::shared_ptr<const TrajectoryView> shown_view_;  // keeps rendered_.view's address unique
  Eigen::Matrix4f view_projection_ = Eigen::Matrix4f::Identity();
  ScreenRect view_;
  bool fit_pending_ = true;
  bool auto_fit_ = true;
  bool up_known_ = false;
  bool by_error_ = false;
  float max_error_ = 0.0f;
  float scene_radius_ = 1.0f;
};

}  // namespace nirslam::ui
