#pragma once

#include <stdexcept>

namespace nirslam::app {

// A front end could not start: no display, no GLFW window, no EGL, no OpenGL 3.3. Thrown before
// anything was shown, so a caller may fall back to another front end.
class FrontendUnavailable : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

}  // namespace nirslam::app
