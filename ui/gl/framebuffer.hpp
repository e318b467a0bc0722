#pragma once

#include <opencv2/core/mat.hpp>

#include "ui/gl/gl.hpp"

namespace nirslam::ui::gl {

// An offscreen render target: an RGBA8 colour texture attached to a framebuffer object. Used by
// panels that draw with their own shaders (shown with ImGui::Image) and by the headless front
// end, which renders the whole UI into one. Move-only.
class Framebuffer {
public:
  Framebuffer() = default;
  ~Framebuffer();
  Framebuffer(Framebuffer&& other) noexcept;
  Framebuffer& operator=(Framebuffer&& other) noexcept;
  Framebuffer(const Framebuffer&) = delete;
  Framebuffer& operator=(const Framebuffer&) = delete;

  // (Re)allocates the colour buffer when the size changes; a no-op otherwise. Throws
  // std::runtime_error when the framebuffer is incomplete or the size is not positive.
  // With `with_depth`, a 24-bit depth renderbuffer is attached too (the 3-D view needs one).
  void resize(int width, int height, bool with_depth = false);

  // Binds it for drawing and sets the viewport to cover it.
  void bind() const;

  GLuint id() const { return fbo_; }
  GLuint texture() const { return texture_; }
  int width() const { return width_; }
  int height() const { return height_; }

  // The colour buffer as CV_8UC4 RGBA, top row first (GL stores the bottom row first).
  cv::Mat read_rgba() const;

private:
  void release();
  GLuint fbo_ = 0;
  GLuint texture_ = 0;
  GLuint depth_ = 0;
  int width_ = 0;
  int height_ = 0;
};

// Reads the currently bound read framebuffer's region (0, 0, width, height) as CV_8UC4 RGBA,
// top row first.
cv::Mat read_pixels_rgba(int width, int height);

// Saves the draw/read framebuffer bindings and the viewport, and restores them when it goes out
// of scope, so a panel can render offscreen in the middle of a UI frame.
class FramebufferBindingGuard {
public:
  FramebufferBindingGuard();
  ~FramebufferBindingGuard();
  FramebufferBindingGuard(const FramebufferBindingGuard&) = delete;
  FramebufferBindingGuard& operator=(const FramebufferBindingGuard&) = delete;

private:
  GLint draw_ = 0;
  GLint read_ = 0;
  GLint viewport_[4] = {0, 0, 0, 0};
};

}  // namespace nirslam::ui::gl
