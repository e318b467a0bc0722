#include "ui/application.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

constexpr ImGuiWindowFlags kTileFlags = ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize |
                                        ImGuiWindowFlags_NoCollapse | ImGuiWindowFlags_NoSavedSettings |
                                        ImGuiWindowFlags_NoBringToFrontOnFocus | ImGuiWindowFlags_NoScrollbar |
                                        ImGuiWindowFlags_NoScrollWithMouse;
constexpr ImGuiWindowFlags kBarFlags = kTileFlags | ImGuiWindowFlags_NoTitleBar;

bool begin_tile(const char* name, const ScreenRect& rect, ImGuiWindowFlags flags) {
  ImGui::SetNextWindowPos(rect.min);
  ImGui::SetNextWindowSize(rect.size());
  return ImGui::Begin(name, nullptr, flags);
}

}  // namespace

Application::Application(const std::filesystem::path& shader_dir, CommandSink post)
    : post_(std::move(post)), feed_(shader_dir), view3d_(shader_dir) {}

Application::Layout Application::compute_layout(ImVec2 display) const {
  const ImGuiStyle& style = ImGui::GetStyle();
  Layout layout;
  const float w = std::floor(display.x);
  const float h = std::floor(display.y);
  float top = 0.0f;
  float bottom = h;
  if (panels.controls) {
    const float bar = std::round(ImGui::GetFrameHeight() + 2.0f * style.WindowPadding.y + 2.0f);
    layout.controls = {ImVec2(0.0f, 0.0f), ImVec2(w, bar)};
    top = bar;
  }
  if (panels.status) {
    const float bar = std::round(ImGui::GetTextLineHeight() + 2.0f * 5.0f);
    layout.status = {ImVec2(0.0f, h - bar), ImVec2(w, h)};
    bottom = h - bar;
  }
  // The measurement column: about a third of the width, readable at any window size.
  const float width = std::clamp(std::round(0.34f * w), std::min(380.0f, 0.5f * w), 600.0f);
  const bool left_panels = panels.feed || panels.view3d || panels.illumination || panels.photometric;
  const float split = !panels.entropy ? w : left_panels ? w - width : 0.0f;
  if (panels.entropy) layout.entropy = {ImVec2(split, top), ImVec2(w, bottom)};
  // Under the feed and the 3-D view, a strip for the illumination and photometric tabs: wide
  // enough for the plots side by side, short enough to leave the views most of the height.
  const bool strip = panels.illumination || panels.photometric;
  const bool views = panels.feed || panels.view3d;
  float strip_top = bottom;
  if (strip) {
    const float middle = bottom - top;
    strip_top = views ? bottom - std::clamp(std::round(0.36f * middle), std::min(240.0f, std::round(0.45f * middle)), 360.0f)
                      : top;
    layout.strip = {ImVec2(0.0f, strip_top), ImVec2(split, bottom)};
  }
  // The feed keeps the larger share: a 4:3 frame needs more width than the 3-D view.
  const float view_split = !panels.view3d ? split : !panels.feed ? 0.0f : std::round(0.55f * split);
  if (panels.feed) layout.feed = {ImVec2(0.0f, top), ImVec2(view_split, strip_top)};
  if (panels.view3d) layout.view3d = {ImVec2(view_split, top), ImVec2(split, strip_top)};
  return layout;
}

void Application::draw(const Snapshot& snapshot) {
  handle_shortcuts(snapshot);
  layout_ = compute_layout(ImGui::GetIO().DisplaySize);

  if (panels.controls) {
    ImGui::PushStyleColor(ImGuiCol_WindowBg, to_vec4(rgba(24, 26, 30)));
    if (begin_tile("##controls", layout_.controls, kBarFlags)) controls_.draw(snapshot, post_);
    ImGui::End();
    ImGui::PopStyleColor();
  }
  if (panels.feed) {
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(8.0f, 6.0f));
    if (begin_tile("Feed###feed", layout_.feed, kTileFlags)) feed_.draw(snapshot);
    ImGui::End();
    ImGui::PopStyleVar();
  }
  if (panels.entropy) {
    if (begin_tile("Image quality###entropy", layout_.entropy, kTileFlags)) entropy_.draw(snapshot);
    ImGui::End();
  }
  if (panels.view3d) {
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(8.0f, 6.0f));
    if (begin_tile("3-D view###view3d", layout_.view3d, kTileFlags)) view3d_.draw(snapshot);
    ImGui::End();
    ImGui::PopStyleVar();
  }
  if (panels.illumination || panels.photometric) draw_strip(snapshot);
  if (panels.status) {
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(10.0f, 5.0f));
    ImGui::PushStyleColor(ImGuiCol_WindowBg, to_vec4(rgba(24, 26, 30)));
    if (begin_tile("##status", layout_.status, kBarFlags)) status_.draw(snapshot);
    ImGui::End();
    ImGui::PopStyleColor();
    ImGui::PopStyleVar();
  }
}

void Application::draw_strip(const Snapshot& snapshot) {
  const bool both = panels.illumination && panels.photometric;
  const char* title = both ? "##strip" : panels.illumination ? "Illumination###strip" : "Photometric###strip";
  if (begin_tile(title, layout_.strip, both ? kBarFlags : kTileFlags)) {
    if (!both) {
      if (panels.illumination)
        illumination_.draw(snapshot, post_);
      else
        photometric_.draw(snapshot);
    } else if (ImGui::BeginTabBar("##strip_tabs")) {
      const auto flags = [this](StripTab tab) {
        return requested_tab_ == tab ? ImGuiTabItemFlags_SetSelected : ImGuiTabItemFlags_None;
      };
      if (ImGui::BeginTabItem("Illumination", nullptr, flags(StripTab::Illumination))) {
        illumination_.draw(snapshot, post_);
        ImGui::EndTabItem();
      }
      if (ImGui::BeginTabItem("Photometric", nullptr, flags(StripTab::Photometric))) {
        photometric_.draw(snapshot);
        ImGui::EndTabItem();
      }
      requested_tab_.reset();
      ImGui::EndTabBar();
    }
  }
  ImGui::End();
}

void Application::handle_shortcuts(const Snapshot& snapshot) {
  const ImGuiIO& io = ImGui::GetIO();
  if (!post_ || io.WantTextInput) return;
  const bool has_source = !snapshot.source.kind.empty() || !snapshot.source.description.empty();
  if (!has_source) return;
  const int space = ImGui::GetKeyIndex(ImGuiKey_Space);
  if (space >= 0 && ImGui::IsKeyPressed(space, false)) {
    if (snapshot.state == WorkerState::Running)
      post_(command::Pause{});
    else
      post_(command::Start{});
  }
  // Letters have no ImGuiKey in 1.86; the typed character is layout-aware and backend-neutral.
  for (const ImWchar c : io.InputQueueCharacters)
    if ((c == 's' || c == 'S') && snapshot.state != WorkerState::Running) post_(command::Step{});
}

}  // namespace nirslam::ui
