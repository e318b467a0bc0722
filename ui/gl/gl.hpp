#pragma once

// The one way the project declares OpenGL: core entry points straight from libOpenGL (glvnd),
// which exports every core GL function, so no loader and no GLX are needed. This header is also
// force-included into Dear ImGui's OpenGL3 backend (IMGUI_IMPL_OPENGL_LOADER_CUSTOM), so the
// backend and the project's renderers use the same declarations in a window or headless (EGL).
#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/gl.h>
#include <GL/glext.h>
