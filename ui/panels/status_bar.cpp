#include "ui/panels/status_bar.hpp"

#include <algorithm>
#include <string>

#include <fmt/format.h>
#include <imgui.h>

#include "ui/panels/control_bar.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {

void StatusBar::draw(const Snapshot& snapshot) {
  const ImGuiIO& io = ImGui::GetIO();
  const ImU32 message_colour = snapshot.state == WorkerState::Failed ? colours::state_failed : colours::text;
  const std::string message = snapshot.message.empty() ? std::string(state_label(snapshot.state)) : snapshot.message;

  const StageTimings& t = snapshot.timings;
  std::string stages = fmt::format("read {:.1f} · quality {:.1f}", t.read_ms, t.quality_ms);
  if (snapshot.photometric && snapshot.photometric->enabled) stages += fmt::format(" · photometric {:.1f}", t.photometric_ms);
  if (snapshot.trajectory && snapshot.trajectory->enabled)
    stages += fmt::format(" · odometry {:.1f} (mapping {:.1f})", t.odometry_ms, t.mapping_ms);
  const std::string right =
      fmt::format("{} frames · {:.1f} fps · {} ms   |   UI {:.0f} fps   |   Space pause/resume · S step · H shortcuts",
                  snapshot.frames_processed, snapshot.processing_fps, stages, io.Framerate);
  const float right_width = ImGui::CalcTextSize(right.c_str()).x;
  const float right_x = ImGui::GetWindowContentRegionMax().x - right_width;

  ImGui::TextColored(to_vec4(colours::text_dim), "Worker");
  ImGui::SameLine(0.0f, 8.0f);
  const ImVec2 p = ImGui::GetCursorScreenPos();
  const float message_width = std::max(20.0f, right_x - ImGui::GetCursorPosX() - 16.0f);
  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->PushClipRect(p, ImVec2(p.x + message_width, p.y + ImGui::GetTextLineHeight()), true);
  draw->AddText(p, message_colour, message.c_str());
  draw->PopClipRect();
  ImGui::Dummy(ImVec2(message_width, ImGui::GetTextLineHeight()));
  if (ImGui::IsItemHovered() && !snapshot.message.empty()) ImGui::SetTooltip("%s", snapshot.message.c_str());
  ImGui::SameLine(std::max(right_x, ImGui::GetCursorPosX()));
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", right.c_str());
}

}  // namespace nirslam::ui
