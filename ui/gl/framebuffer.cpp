#include "ui/gl/framebuffer.hpp"

#include <stdexcept>
#include <string>
#include <utility>

#include <opencv2/core.hpp>

namespace nirslam::ui::gl {

Framebuffer::~Framebuffer() { release(); }

Framebuffer::Framebuffer(Framebuffer&& other) noexcept
    : fbo_(std::exchange(other.fbo_, 0)),
      texture_(std::exchange(other.texture_, 0)),
      depth_(std::exchange(other.depth_, 0)),
      width_(std::exchange(other.width_, 0)),
      height_(std::exchange(other.height_, 0)) {}

Framebuffer& Framebuffer::operator=(Framebuffer&& other) noexcept {
  if (this != &other) {
    release();
    fbo_ = std::exchange(other.fbo_, 0);
    texture_ = std::exchange(other.texture_, 0);
    depth_ = std::exchange(other.depth_, 0);
    width_ = std::exchange(other.width_, 0);
    height_ = std::exchange(other.height_, 0);
  }
  return *this;
}

void Framebuffer::release() {
  if (fbo_ != 0) glDeleteFramebuffers(1, &fbo_);
  if (texture_ != 0) glDeleteTextures(1, &texture_);
  if (depth_ != 0) glDeleteRenderbuffers(1, &depth_);
  fbo_ = texture_ = depth_ = 0;
  width_ = height_ = 0;
}

void Framebuffer::resize(int width, int height, bool with_depth) {
  if (width <= 0 || height <= 0)
    throw std::runtime_error("framebuffer size must be positive, got " + std::to_string(width) + "x" +
                             std::to_string(height));
  if (fbo_ != 0 && width == width_ && height == height_ && with_depth == (depth_ != 0)) return;

  GLint previous_texture = 0;
  glGetIntegerv(GL_TEXTURE_BINDING_2D, &previous_texture);
  if (texture_ == 0) glGenTextures(1, &texture_);
  glBindTexture(GL_TEXTURE_2D, texture_);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, width, height, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
  // Shown 1:1 on screen; nearest keeps it exact.
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D, static_cast<GLuint>(previous_texture));

  FramebufferBindingGuard guard;
  if (fbo_ == 0) glGenFramebuffers(1, &fbo_);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture_, 0);
  if (with_depth) {
    if (depth_ == 0) glGenRenderbuffers(1, &depth_);
    glBindRenderbuffer(GL_RENDERBUFFER, depth_);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_);
  } else if (depth_ != 0) {
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, 0);
    glDeleteRenderbuffers(1, &depth_);
    depth_ = 0;
  }
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    release();
    throw std::runtime_error("offscreen framebuffer " + std::to_string(width) + "x" + std::to_string(height) +
                             " is incomplete (status 0x" + cv::format("%04X", status) + ")");
  }
  width_ = width;
  height_ = height;
}

void Framebuffer::bind() const {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glViewport(0, 0, width_, height_);
}

cv::Mat Framebuffer::read_rgba() const {
  FramebufferBindingGuard guard;
  glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
  return read_pixels_rgba(width_, height_);
}

cv::Mat read_pixels_rgba(int width, int height) {
  cv::Mat bottom_up(height, width, CV_8UC4);
  GLint previous_alignment = 4;
  glGetIntegerv(GL_PACK_ALIGNMENT, &previous_alignment);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, bottom_up.data);
  glPixelStorei(GL_PACK_ALIGNMENT, previous_alignment);
  cv::Mat top_down;
  cv::flip(bottom_up, top_down, 0);
  return top_down;
}

FramebufferBindingGuard::FramebufferBindingGuard() {
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_);
  glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &read_);
  glGetIntegerv(GL_VIEWPORT, viewport_);
}

FramebufferBindingGuard::~FramebufferBindingGuard() {
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, static_cast<GLuint>(draw_));
  glBindFramebuffer(GL_READ_FRAMEBUFFER, static_cast<GLuint>(read_));
  glViewport(viewport_[0], viewport_[1], viewport_[2], viewport_[3]);
}

}  // namespace nirslam::ui::gl
