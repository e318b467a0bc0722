#include "ui/panels/shortcut_help.hpp"

#include <imgui.h>

#include "ui/shortcuts.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {

void ShortcutHelp::draw(const ScreenRect& area) {
  drawn_ = {};
  if (!visible || area.empty()) return;
  ImGui::SetNextWindowPos(area.centre(), ImGuiCond_Always, ImVec2(0.5f, 0.5f));
  ImGui::SetNextWindowBgAlpha(0.96f);
  if (ImGui::Begin("Keyboard shortcuts###shortcut_help", &visible,
                   ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoCollapse |
                       ImGuiWindowFlags_NoMove)) {
    if (ImGui::BeginTable("##shortcuts", 2, ImGuiTableFlags_RowBg | ImGuiTableFlags_PadOuterX)) {
      for (const Shortcut& s : shortcuts()) {
        ImGui::TableNextRow();
        ImGui::TableNextColumn();
        ImGui::TextColored(to_vec4(colours::accent), "%s", s.label);
        ImGui::TableNextColumn();
        ImGui::TextUnformatted(s.action);
      }
      ImGui::TableNextRow();
      ImGui::TableNextColumn();
      ImGui::TextColored(to_vec4(colours::accent), "Ctrl+Q");
      ImGui::TableNextColumn();
      ImGui::TextUnformatted("quit (settings are saved)");
      ImGui::EndTable();
    }
    ImGui::TextColored(to_vec4(colours::text_dim), "Keys do nothing while a text field has the keyboard.");
    const ImVec2 min = ImGui::GetWindowPos();
    drawn_ = {min, ImVec2(min.x + ImGui::GetWindowSize().x, min.y + ImGui::GetWindowSize().y)};
  }
  ImGui::End();
}

}  // namespace nirslam::ui
