#pragma once

#include <string>

namespace nirslam::app {

// An OpenGL 3.3 core context without any window or surface, through EGL: Mesa's surfaceless
// platform (EGL_PLATFORM_SURFACELESS_MESA via eglGetPlatformDisplayEXT) when available, else
// EGL_DEFAULT_DISPLAY. Rendering goes to framebuffer objects. Current on the creating thread
// from construction to destruction; the destructor makes the previously current context current
// again. Throws FrontendUnavailable saying which step failed.
class EglContext {
public:
  EglContext();
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  // "llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core Profile) Mesa 22.3.6", for logs.
  const std::string& description() const { return description_; }
  // "surfaceless" or "default".
  const std::string& platform() const { return platform_; }

private:
  void* display_ = nullptr;  // EGLDisplay
  void* context_ = nullptr;  // EGLContext
  void* previous_display_ = nullptr;  // what was current before, restored by the destructor
  void* previous_context_ = nullptr;
  void* previous_draw_ = nullptr;
  void* previous_read_ = nullptr;
  std::string description_;
  std::string platform_;
};

}  // namespace nirslam::app
