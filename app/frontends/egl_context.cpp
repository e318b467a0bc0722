#include "frontends/egl_context.hpp"

#include <string>

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <fmt/format.h>

#include "frontends/frontend_error.hpp"
#include "ui/gl/gl.hpp"

namespace nirslam::app {
namespace {

std::string egl_error_name(EGLint error) {
  switch (error) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    default: return fmt::format("EGL error 0x{:04X}", error);
  }
}

[[noreturn]] void fail(const std::string& what) {
  throw FrontendUnavailable(fmt::format("headless OpenGL (EGL) unavailable: {} ({}). Headless rendering needs "
                                        "libEGL with Mesa (package libegl-mesa0) or a GPU driver.",
                                        what, egl_error_name(eglGetError())));
}

bool has_extension(const char* list, const std::string& name) {
  if (list == nullptr) return false;
  const std::string all = std::string(" ") + list + " ";
  return all.find(" " + name + " ") != std::string::npos;
}

}  // namespace

EglContext::EglContext() {
  previous_display_ = eglGetCurrentDisplay();
  previous_context_ = eglGetCurrentContext();
  previous_draw_ = eglGetCurrentSurface(EGL_DRAW);
  previous_read_ = eglGetCurrentSurface(EGL_READ);
  EGLDisplay display = EGL_NO_DISPLAY;
  // Client extensions (queried without a display) say whether platform displays exist.
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
    const auto get_platform_display =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (get_platform_display != nullptr) {
      display = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
      platform_ = "surfaceless";
    }
  }
  EGLint major = 0;
  EGLint minor = 0;
  if (display == EGL_NO_DISPLAY || eglInitialize(display, &major, &minor) != EGL_TRUE) {
    display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    platform_ = "default";
    if (display == EGL_NO_DISPLAY) fail("no EGL display");
    if (eglInitialize(display, &major, &minor) != EGL_TRUE) fail("eglInitialize failed");
  }
  display_ = display;

  if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE) {
    fail("the EGL implementation has no desktop OpenGL (eglBindAPI(EGL_OPENGL_API) failed)");
  }
  const char* display_extensions = eglQueryString(display, EGL_EXTENSIONS);
  if (!has_extension(display_extensions, "EGL_KHR_surfaceless_context")) {
    fail("EGL_KHR_surfaceless_context is not supported");
  }

  // A config is only needed when the driver lacks configless contexts.
  EGLConfig config = nullptr;
  if (!has_extension(display_extensions, "EGL_KHR_no_config_context") &&
      !has_extension(display_extensions, "EGL_MESA_configless_context")) {
    const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint count = 0;
    if (eglChooseConfig(display, config_attributes, &config, 1, &count) != EGL_TRUE || count < 1) {
      fail("no EGL config for desktop OpenGL");
    }
  }
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 3,
                                       EGL_CONTEXT_MINOR_VERSION, 3,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
  if (context == EGL_NO_CONTEXT) {
    fail("cannot create an OpenGL 3.3 core context");
  }
  if (eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE) {
    eglDestroyContext(display, context);
    fail("eglMakeCurrent without a surface failed");
  }
  context_ = context;
  const auto text = [](GLenum name) {
    const GLubyte* value = glGetString(name);
    return value != nullptr ? std::string(reinterpret_cast<const char*>(value)) : std::string("?");
  };
  description_ = fmt::format("{}, OpenGL {} (EGL {}.{}, {} platform)", text(GL_RENDERER), text(GL_VERSION), major,
                             minor, platform_);
}

EglContext::~EglContext() {
  const auto display = static_cast<EGLDisplay>(display_);
  eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(display, static_cast<EGLContext>(context_));
  // The display is process-wide and may carry other contexts (nested headless renders in tests),
  // so it is not terminated here; the driver releases it at exit. What was current comes back.
  if (previous_context_ != EGL_NO_CONTEXT && previous_display_ != EGL_NO_DISPLAY)
    eglMakeCurrent(static_cast<EGLDisplay>(previous_display_), static_cast<EGLSurface>(previous_draw_),
                   static_cast<EGLSurface>(previous_read_), static_cast<EGLContext>(previous_context_));
}

}  // namespace nirslam::app
