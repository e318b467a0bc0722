#include "ui/panels/notification_area.hpp"

#include <algorithm>
#include <utility>

#include <imgui.h>

#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

ImU32 severity_colour(NotificationArea::Severity severity) {
  switch (severity) {
    case NotificationArea::Severity::Notice: return colours::state_finished;
    case NotificationArea::Severity::Warning: return colours::banner_dark;
    case NotificationArea::Severity::Error: return colours::state_failed;
  }
  return colours::text;
}

const char* severity_label(NotificationArea::Severity severity) {
  switch (severity) {
    case NotificationArea::Severity::Notice: return "Note";
    case NotificationArea::Severity::Warning: return "Warning";
    case NotificationArea::Severity::Error: return "Error";
  }
  return "";
}

}  // namespace

void NotificationArea::push(Severity severity, std::string text) {
  if (text.empty()) return;
  const double now = ImGui::GetCurrentContext() != nullptr ? ImGui::GetTime() : 0.0;
  for (Item& item : items_)
    if (item.text == text && item.severity == severity) {
      ++item.repeats;
      item.posted_at = now;
      return;
    }
  items_.push_front(Item{severity, std::move(text), now});
  // Old notices go first; errors are kept until the operator dismisses them.
  while (items_.size() > 16) items_.pop_back();
}

void NotificationArea::observe(const Snapshot& snapshot) {
  if (snapshot.sequence == last_sequence_ && snapshot.state == last_state_) return;
  if (snapshot.state == WorkerState::Failed && last_state_ != WorkerState::Failed)
    push(Severity::Error, snapshot.message.empty() ? std::string("The worker stopped with an error.") : snapshot.message);
  last_state_ = snapshot.state;
  last_sequence_ = snapshot.sequence;
}

void NotificationArea::draw(const ScreenRect& area) {
  drawn_ = {};
  const double now = ImGui::GetTime();
  std::erase_if(items_, [now](const Item& item) {
    return item.severity == Severity::Notice && now - item.posted_at > kNoticeSeconds;
  });
  if (items_.empty() || area.empty()) return;

  const float margin = 10.0f;
  const float width = std::min(460.0f, area.width() - 2.0f * margin);
  // Below the title bar and the panels' two tool rows, so their buttons stay reachable.
  float y = area.min.y + margin + 3.0f * ImGui::GetFrameHeightWithSpacing();
  const ImGuiStyle& style = ImGui::GetStyle();
  std::size_t shown = 0;
  for (auto it = items_.begin(); it != items_.end() && shown < kMaxShown; ++shown) {
    const Item& item = *it;
    ImGui::SetNextWindowPos(ImVec2(area.max.x - margin - width, y));
    ImGui::SetNextWindowSize(ImVec2(width, 0.0f));
    ImGui::SetNextWindowBgAlpha(0.94f);
    ImGui::PushStyleColor(ImGuiCol_Border, to_vec4(severity_colour(item.severity)));
    ImGui::PushStyleVar(ImGuiStyleVar_WindowBorderSize, 1.5f);
    const std::string id = "##notification" + std::to_string(shown);
    bool dismissed = false;
    if (ImGui::Begin(id.c_str(), nullptr,
                     ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoSavedSettings |
                         ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav | ImGuiWindowFlags_NoMove)) {
      ImGui::TextColored(to_vec4(severity_colour(item.severity)), "%s", severity_label(item.severity));
      if (item.repeats > 1) {
        ImGui::SameLine();
        ImGui::TextColored(to_vec4(colours::text_dim), "(x%d)", item.repeats);
      }
      ImGui::SameLine(width - style.WindowPadding.x - ImGui::CalcTextSize("Dismiss").x - 2.0f * style.FramePadding.x);
      dismissed = ImGui::SmallButton("Dismiss");
      ImGui::PushTextWrapPos(width - style.WindowPadding.x);
      ImGui::TextUnformatted(item.text.c_str());
      ImGui::PopTextWrapPos();
      const ImVec2 min = ImGui::GetWindowPos();
      const ImVec2 max(min.x + ImGui::GetWindowSize().x, min.y + ImGui::GetWindowSize().y);
      drawn_.min = drawn_.empty() ? min : ImVec2(std::min(drawn_.min.x, min.x), std::min(drawn_.min.y, min.y));
      drawn_.max = ImVec2(std::max(drawn_.max.x, max.x), std::max(drawn_.max.y, max.y));
      y = max.y + 6.0f;
    }
    ImGui::End();
    ImGui::PopStyleVar();
    ImGui::PopStyleColor();
    it = dismissed ? items_.erase(it) : std::next(it);
  }
}

}  // namespace nirslam::ui
