#pragma once

#include <cstdint>

#include <filesystem>

#include <imgui.h>
#include <opencv2/core/mat.hpp>

#include "nirslam/worker/snapshot.hpp"
#include "ui/gl/framebuffer.hpp"
#include "ui/gl/shader.hpp"
#include "ui/gl/texture.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// The live frame. The grey image is drawn by shaders/image_quad.{vert,frag} into an offscreen
// framebuffer the size of the panel (normalised by the frame's bit depth, clipped pixels
// optionally marked: saturated in red, black in blue) and shown with ImGui::Image. Fitted to the
// panel with its aspect ratio kept; mouse wheel zooms about the cursor, dragging pans,
// double-click fits again. Overlays: frame info, processing rate, pixel value under the cursor.
class FeedPanel {
public:
  // Loads image_quad.vert/.frag from `shader_dir`; throws gl::ShaderError naming the file.
  // Needs a current GL context, for this call and for the panel's whole life.
  explicit FeedPanel(const std::filesystem::path& shader_dir);
  ~FeedPanel();
  FeedPanel(const FeedPanel&) = delete;
  FeedPanel& operator=(const FeedPanel&) = delete;

  // Draws into the current ImGui window: a tool row, then the image filling the rest.
  void draw(const Snapshot& snapshot);

  bool highlight_clipping = true;
  bool show_info = true;  // frame info and processing rate overlays
  // Show the photometrically corrected frame G(I)/V (what the odometry sees) instead of the raw
  // one, when the pipeline mode corrects frames.
  bool show_corrected = false;
  // The odometry's active points as seen from the current frame, coloured by inverse depth.
  bool show_points = true;
  int points_drawn() const { return points_drawn_; }
  bool showing_corrected() const { return showing_corrected_; }

  // The view. zoom 1 is the whole frame fitted to the panel; pan is the image centre's offset
  // from the panel centre in screen pixels.
  void fit();
  void set_view(float zoom, ImVec2 pan = ImVec2(0.0f, 0.0f));
  float zoom() const { return zoom_; }
  ImVec2 pan() const { return pan_; }

  // Geometry of the last draw(), in screen pixels, for hit tests and the screenshot tests.
  const ScreenRect& view_rect() const { return view_; }    // the image area of the panel
  const ScreenRect& image_rect() const { return image_; }  // the frame (may extend past the view)
  float scale() const { return scale_; }                   // screen pixels per image pixel

private:
  void draw_tool_row(const Frame* frame, bool has_corrected);
  void handle_input(const Frame& frame, bool hovered, bool active);
  void update_geometry(const Frame& frame);
  void render(const Frame& frame);
  void draw_overlays(const Snapshot& snapshot, const Frame& frame, bool hovered);
  void draw_tracked_points(const TrajectoryView& view);

  gl::Program program_;
  gl::GreyTexture texture_;
  gl::Framebuffer target_;
  GLuint vertex_array_ = 0;
  cv::Mat uploaded_;  // the frame now in texture_; holding it keeps its buffer (and address) alive
  // What the offscreen target last showed: when nothing of it changed (the UI draws at 60 Hz,
  // frames arrive at 20-30), the target is composited again without re-rendering it, which on a
  // software rasteriser is most of the panel's cost.
  struct RenderKey {
    const void* image = nullptr;
    float rect[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    int target_w = 0;
    int target_h = 0;
    bool highlight = false;
    std::uint32_t max_code = 0;
    bool operator==(const RenderKey&) const = default;
  };
  RenderKey rendered_;
  GLint u_rect_ = -1;
  GLint u_target_size_ = -1;
  GLint u_image_ = -1;
  GLint u_container_max_ = -1;
  GLint u_max_code_ = -1;
  GLint u_highlight_ = -1;
  GLint u_saturated_colour_ = -1;
  GLint u_black_colour_ = -1;

  float zoom_ = 1.0f;
  ImVec2 pan_{0.0f, 0.0f};
  ScreenRect view_;
  ScreenRect image_;
  float scale_ = 0.0f;
  bool showing_corrected_ = false;
  int points_drawn_ = 0;
  cv::Mat corrected_source_;  // the snapshot's float image last converted
  cv::Mat corrected_grey_;    // its 8-bit version (a new buffer per frame: the texture cache keys on it)
};

}  // namespace nirslam::ui
