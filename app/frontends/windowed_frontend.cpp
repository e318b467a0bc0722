#include "frontends/windowed_frontend.hpp"

#include <algorithm>
#include <chrono>
#include <string>
#include <thread>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "ui/gl/gl.hpp"

#define GLFW_INCLUDE_NONE  // GL comes from ui/gl/gl.hpp
#include <GLFW/glfw3.h>
#include <imgui_impl_glfw.h>

#include "frontends/frontend_error.hpp"
#include "frontends/headless_frontend.hpp"
#include "ui/application.hpp"
#include "ui/gl/framebuffer.hpp"
#include "ui/gl/shader.hpp"
#include "ui/ui_context.hpp"

namespace nirslam::app {
namespace {

std::string g_last_glfw_error;

void on_glfw_error(int code, const char* description) {
  g_last_glfw_error = fmt::format("{} (GLFW error 0x{:X})", description != nullptr ? description : "?", code);
  spdlog::debug("GLFW: {}", g_last_glfw_error);
}

// glfwInit/glfwTerminate and the window, released in the right order on every path.
class GlfwWindow {
public:
  explicit GlfwWindow(const WindowedOptions& options) {
    glfwSetErrorCallback(on_glfw_error);
    if (glfwInit() != GLFW_TRUE)
      throw FrontendUnavailable("cannot open a window: GLFW initialisation failed: " + g_last_glfw_error);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_SCALE_TO_MONITOR, GLFW_TRUE);
    const UiPreferences* saved = options.size_from_preferences ? options.preferences : nullptr;
    if (saved != nullptr && saved->window_maximised) glfwWindowHint(GLFW_MAXIMIZED, GLFW_TRUE);
    window_ = glfwCreateWindow(saved != nullptr ? saved->window_width : options.width,
                               saved != nullptr ? saved->window_height : options.height, options.title.c_str(), nullptr,
                               nullptr);
    if (window_ == nullptr) {
      glfwTerminate();
      throw FrontendUnavailable("cannot open an OpenGL 3.3 core window: " + g_last_glfw_error);
    }
    glfwSetWindowSizeLimits(window_, 800, 500, GLFW_DONT_CARE, GLFW_DONT_CARE);
    if (saved != nullptr && saved->window_x && saved->window_y) glfwSetWindowPos(window_, *saved->window_x, *saved->window_y);
    glfwMakeContextCurrent(window_);
    glfwSwapInterval(1);
  }
  ~GlfwWindow() {
    glfwDestroyWindow(window_);
    glfwTerminate();
  }
  GlfwWindow(const GlfwWindow&) = delete;
  GlfwWindow& operator=(const GlfwWindow&) = delete;
  GLFWwindow* get() const { return window_; }

private:
  GLFWwindow* window_ = nullptr;
};

class GlfwPlatform {
public:
  explicit GlfwPlatform(GLFWwindow* window) {
    if (!ImGui_ImplGlfw_InitForOpenGL(window, true)) throw FrontendUnavailable("cannot initialise the ImGui GLFW backend");
  }
  ~GlfwPlatform() { ImGui_ImplGlfw_Shutdown(); }
  GlfwPlatform(const GlfwPlatform&) = delete;
  GlfwPlatform& operator=(const GlfwPlatform&) = delete;
};

}  // namespace

void run_windowed(Worker& worker, const WindowedOptions& options) {
  if (!options.screenshot.empty()) check_screenshot_folder(options.screenshot);
  GlfwWindow window(options);
  float scale_x = 1.0f;
  float scale_y = 1.0f;
  glfwGetWindowContentScale(window.get(), &scale_x, &scale_y);
  const float scale = std::clamp(std::max(scale_x, scale_y), 1.0f, 4.0f);
  spdlog::debug("OpenGL: {} {} (content scale {:.2f})", reinterpret_cast<const char*>(glGetString(GL_RENDERER)),
                reinterpret_cast<const char*>(glGetString(GL_VERSION)), scale);

  ui::UiContext ui({.scale = scale});
  GlfwPlatform platform(window.get());
  ui::Application app(ui::gl::find_shader_dir(), [&worker](Command c) { worker.post(std::move(c)); });
  if (options.preferences != nullptr) app.apply(*options.preferences);
  if (!options.tab.empty()) app.select_tab(options.tab);
  app.set_session_actions(options.session_actions);
  if (!options.current_source.empty()) app.session().set_current(options.current_source);
  for (const std::string& warning : options.startup_warnings)
    app.notifications().push(ui::NotificationArea::Severity::Warning, warning);

  worker.post(command::Start{});
  bool screenshot_pending = !options.screenshot.empty();
  using Clock = std::chrono::steady_clock;
  constexpr auto kFramePeriod = std::chrono::microseconds(16667);
  while (glfwWindowShouldClose(window.get()) == GLFW_FALSE) {
    const auto frame_start = Clock::now();
    const std::shared_ptr<const Snapshot> snapshot = worker.snapshot();
    // While frames arrive the UI redraws continuously; otherwise it sleeps until input arrives,
    // or 50 ms, to pick up what a command (Step) changed without spinning.
    if (snapshot->state == WorkerState::Running)
      glfwPollEvents();
    else
      glfwWaitEventsTimeout(0.05);

    // Ctrl+Q closes the window like its close button.
    GLFWwindow* w = window.get();
    if ((glfwGetKey(w, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS || glfwGetKey(w, GLFW_KEY_RIGHT_CONTROL) == GLFW_PRESS) &&
        glfwGetKey(w, GLFW_KEY_Q) == GLFW_PRESS)
      glfwSetWindowShouldClose(w, GLFW_TRUE);

    ImGui_ImplGlfw_NewFrame();
    ui.begin_frame();
    app.draw(*snapshot);
    ui.end_frame();

    if (screenshot_pending && (snapshot->frames_processed >= options.screenshot_after_frames ||
                               snapshot->state == WorkerState::Finished || snapshot->state == WorkerState::Failed)) {
      screenshot_pending = false;
      int width = 0;
      int height = 0;
      glfwGetFramebufferSize(window.get(), &width, &height);
      glReadBuffer(GL_BACK);
      try {
        write_png_rgba(options.screenshot, ui::gl::read_pixels_rgba(width, height));
        spdlog::info("screenshot written to {}", options.screenshot.string());
      } catch (const std::exception& e) {
        spdlog::error("{}", e.what());
      }
    }
    glfwSwapBuffers(window.get());
    // Vsync paces real displays; a virtual one (Xvfb, remote) may not block, so cap at ~60 Hz.
    const auto elapsed = Clock::now() - frame_start;
    if (elapsed < kFramePeriod) std::this_thread::sleep_for(kFramePeriod - elapsed);
  }
  worker.post(command::Stop{});
  if (options.preferences != nullptr) {
    UiPreferences& saved = *options.preferences;
    app.capture(saved);
    GLFWwindow* w = window.get();
    saved.window_maximised = glfwGetWindowAttrib(w, GLFW_MAXIMIZED) == GLFW_TRUE;
    if (!saved.window_maximised) {
      int x = 0;
      int y = 0;
      glfwGetWindowPos(w, &x, &y);
      saved.window_x = x;
      saved.window_y = y;
      glfwGetWindowSize(w, &saved.window_width, &saved.window_height);
    }
  }
  spdlog::debug("window closed; worker stopped");
}

}  // namespace nirslam::app
