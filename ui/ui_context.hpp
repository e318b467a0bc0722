#pragma once

#include <functional>

#include <imgui.h>
#include <opencv2/core/mat.hpp>

#include "ui/gl/framebuffer.hpp"

namespace nirslam::ui {

struct UiContextOptions {
  float scale = 1.0f;  // HiDPI content scale: multiplies font sizes and style metrics
};

// The Dear ImGui context with the project's theme and fonts and the OpenGL3 renderer backend.
// Needs a current OpenGL 3.3 core context (GLFW window or EGL) for its whole life. Front ends
// feed input and the display size (a platform backend, or by hand when headless). One at a time.
class UiContext {
public:
  explicit UiContext(UiContextOptions options = {});
  ~UiContext();
  UiContext(const UiContext&) = delete;
  UiContext& operator=(const UiContext&) = delete;

  // Starts a UI frame; call after the platform backend's NewFrame (or after setting
  // io.DisplaySize and io.DeltaTime by hand).
  void begin_frame();
  // Finishes the frame and draws it into the currently bound framebuffer, clearing it first.
  void end_frame();

  ImGuiContext* context() const { return context_; }

private:
  ImGuiContext* context_ = nullptr;
};

// The UI rendered without a window: a UiContext drawing into an offscreen framebuffer of a fixed
// size, with no platform backend (no mouse unless a caller puts one into ImGuiIO). Used by the
// headless front end and the screenshot tests.
class OffscreenUi {
public:
  OffscreenUi(int width, int height, UiContextOptions options = {});

  // Runs one UI frame: `draw` builds the windows between NewFrame and Render. Input fields of
  // ImGui::GetIO() set before the call (mouse position, buttons, wheel) apply to this frame.
  void frame(const std::function<void()>& draw, double delta_s = 1.0 / 60.0);

  // The last frame as CV_8UC4 RGBA, top row first.
  cv::Mat read_rgba() const { return target_.read_rgba(); }
  int width() const { return target_.width(); }
  int height() const { return target_.height(); }

private:
  UiContext ui_;
  gl::Framebuffer target_;
};

}  // namespace nirslam::ui
