#include "ui/ui_context.hpp"

#include <cfloat>
#include <stdexcept>

#include <imgui_impl_opengl3.h>

#include "ui/gl/gl.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {

UiContext::UiContext(UiContextOptions options) {
  if (glGetString(GL_VERSION) == nullptr)
    throw std::runtime_error("the UI needs a current OpenGL 3.3 context, and none is current");
  IMGUI_CHECKVERSION();
  context_ = ImGui::CreateContext();
  ImGui::SetCurrentContext(context_);
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // the layout is computed from the window size, nothing to persist
  io.LogFilename = nullptr;
  io.ConfigWindowsMoveFromTitleBarOnly = true;
  load_fonts(options.scale);
  apply_style(options.scale);
  if (!ImGui_ImplOpenGL3_Init("#version 330 core")) {
    ImGui::DestroyContext(context_);
    throw std::runtime_error("cannot initialise the ImGui OpenGL3 renderer");
  }
}

UiContext::~UiContext() {
  ImGui::SetCurrentContext(context_);
  ImGui_ImplOpenGL3_Shutdown();
  ImGui::DestroyContext(context_);
}

void UiContext::begin_frame() {
  ImGui::SetCurrentContext(context_);
  ImGui_ImplOpenGL3_NewFrame();
  ImGui::NewFrame();
}

void UiContext::end_frame() {
  ImGui::Render();
  const ImGuiIO& io = ImGui::GetIO();
  glViewport(0, 0, static_cast<GLsizei>(io.DisplaySize.x * io.DisplayFramebufferScale.x),
             static_cast<GLsizei>(io.DisplaySize.y * io.DisplayFramebufferScale.y));
  const ImVec4 clear = to_vec4(colours::window_bg);
  glClearColor(clear.x, clear.y, clear.z, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

OffscreenUi::OffscreenUi(int width, int height, UiContextOptions options) : ui_(options) {
  target_.resize(width, height);
  ImGuiIO& io = ImGui::GetIO();
  io.DisplaySize = ImVec2(static_cast<float>(width), static_cast<float>(height));
  io.DisplayFramebufferScale = ImVec2(1.0f, 1.0f);
  io.MousePos = ImVec2(-FLT_MAX, -FLT_MAX);
}

void OffscreenUi::frame(const std::function<void()>& draw, double delta_s) {
  ImGuiIO& io = ImGui::GetIO();
  io.DisplaySize = ImVec2(static_cast<float>(target_.width()), static_cast<float>(target_.height()));
  io.DeltaTime = delta_s > 0.0 ? static_cast<float>(delta_s) : 1.0f / 60.0f;
  ui_.begin_frame();
  draw();
  gl::FramebufferBindingGuard guard;
  target_.bind();
  ui_.end_frame();
  glFinish();
}

}  // namespace nirslam::ui
