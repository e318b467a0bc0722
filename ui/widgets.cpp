#include "ui/widgets.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

std::string format_tick(double value, int decimals, const char* unit) {
  return fmt::format("{:.{}f}{}", value, decimals, unit != nullptr ? unit : "");
}

void draw_icon(ImDrawList* draw, Icon icon, ImVec2 min, float size, ImU32 colour) {
  const ImVec2 max(min.x + size, min.y + size);
  const float bar = size * 0.3f;
  switch (icon) {
    case Icon::Play:
      draw->AddTriangleFilled(ImVec2(min.x + size * 0.1f, min.y), ImVec2(min.x + size * 0.1f, max.y),
                              ImVec2(max.x, min.y + size * 0.5f), colour);
      break;
    case Icon::Pause:
      draw->AddRectFilled(ImVec2(min.x + size * 0.1f, min.y), ImVec2(min.x + size * 0.1f + bar, max.y), colour);
      draw->AddRectFilled(ImVec2(max.x - size * 0.1f - bar, min.y), ImVec2(max.x - size * 0.1f, max.y), colour);
      break;
    case Icon::Step:
      draw->AddTriangleFilled(min, ImVec2(min.x, max.y), ImVec2(max.x - bar * 0.9f, min.y + size * 0.5f), colour);
      draw->AddRectFilled(ImVec2(max.x - bar * 0.75f, min.y), max, colour);
      break;
    case Icon::Stop:
      draw->AddRectFilled(ImVec2(min.x + size * 0.08f, min.y + size * 0.08f),
                          ImVec2(max.x - size * 0.08f, max.y - size * 0.08f), colour, 1.5f);
      break;
    case Icon::Fit: {
      const float l = size * 0.35f;
      const float t = 1.6f;
      draw->AddLine(min, ImVec2(min.x + l, min.y), colour, t);
      draw->AddLine(min, ImVec2(min.x, min.y + l), colour, t);
      draw->AddLine(ImVec2(max.x, min.y), ImVec2(max.x - l, min.y), colour, t);
      draw->AddLine(ImVec2(max.x, min.y), ImVec2(max.x, min.y + l), colour, t);
      draw->AddLine(ImVec2(min.x, max.y), ImVec2(min.x + l, max.y), colour, t);
      draw->AddLine(ImVec2(min.x, max.y), ImVec2(min.x, max.y - l), colour, t);
      draw->AddLine(max, ImVec2(max.x - l, max.y), colour, t);
      draw->AddLine(max, ImVec2(max.x, max.y - l), colour, t);
      break;
    }
  }
}

}  // namespace

ScreenRect draw_overlay_table(ImDrawList* draw, const ScreenRect& area, Corner corner,
                              const std::vector<OverlayRow>& rows) {
  if (rows.empty()) return {};
  const float pad = 8.0f;
  const float gap = 14.0f;
  const float line = ImGui::GetTextLineHeight();
  const float spacing = 3.0f;
  float label_width = 0.0f;
  float value_width = 0.0f;
  for (const auto& row : rows) {
    label_width = std::max(label_width, ImGui::CalcTextSize(row.label.c_str()).x);
    value_width = std::max(value_width, ImGui::CalcTextSize(row.value.c_str()).x);
  }
  const bool has_labels = label_width > 0.0f;
  const ImVec2 size(2.0f * pad + label_width + (has_labels ? gap : 0.0f) + value_width,
                    2.0f * pad + static_cast<float>(rows.size()) * line +
                        static_cast<float>(rows.size() - 1) * spacing);
  const float margin = 10.0f;
  const bool left = corner == Corner::TopLeft || corner == Corner::BottomLeft;
  const bool top = corner == Corner::TopLeft || corner == Corner::TopRight;
  ScreenRect box;
  box.min.x = left ? area.min.x + margin : area.max.x - margin - size.x;
  box.min.y = top ? area.min.y + margin : area.max.y - margin - size.y;
  box.max = ImVec2(box.min.x + size.x, box.min.y + size.y);

  draw->AddRectFilled(box.min, box.max, colours::overlay_bg, 4.0f);
  float y = box.min.y + pad;
  for (const auto& row : rows) {
    draw->AddText(ImVec2(box.min.x + pad, y), colours::text_dim, row.label.c_str());
    const float value_x = box.min.x + pad + label_width + (has_labels ? gap : 0.0f);
    draw->AddText(ImVec2(value_x, y), row.colour != 0 ? row.colour : colours::text, row.value.c_str());
    y += line + spacing;
  }
  return box;
}

namespace {
float icon_side() { return std::floor(ImGui::GetFontSize() * 0.72f); }
}  // namespace

float icon_button_width(const char* label) {
  const ImGuiStyle& style = ImGui::GetStyle();
  const float text = ImGui::CalcTextSize(label).x;
  return 2.0f * style.FramePadding.x + icon_side() + (text > 0.0f ? style.ItemInnerSpacing.x + text : 0.0f);
}

bool icon_button(const char* id, Icon icon, const char* label, bool enabled, const char* tooltip) {
  const ImGuiStyle& style = ImGui::GetStyle();
  const float height = ImGui::GetFrameHeight();
  const float icon_size = icon_side();
  const ImVec2 text = ImGui::CalcTextSize(label);
  const bool has_text = text.x > 0.0f;
  const ImVec2 size(icon_button_width(label), height);
  if (!enabled) ImGui::BeginDisabled();
  ImGui::PushID(id);
  const bool pressed = ImGui::Button("##icon_button", size);
  ImGui::PopID();
  const ImVec2 min = ImGui::GetItemRectMin();
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImU32 colour = ImGui::GetColorU32(ImGuiCol_Text);
  draw_icon(draw, icon, ImVec2(min.x + style.FramePadding.x, min.y + std::floor(0.5f * (height - icon_size))),
            icon_size, colour);
  if (has_text)
    draw->AddText(ImVec2(min.x + style.FramePadding.x + icon_size + style.ItemInnerSpacing.x,
                         min.y + 0.5f * (height - text.y)),
                  colour, label);
  if (tooltip != nullptr && ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled)) ImGui::SetTooltip("%s", tooltip);
  if (!enabled) ImGui::EndDisabled();
  return pressed && enabled;
}

void badge(const char* text, ImU32 colour) {
  const ImVec2 text_size = ImGui::CalcTextSize(text);
  const float height = ImGui::GetFrameHeight();
  const float dot = 4.0f;
  const float pad = 8.0f;
  const ImVec2 size(pad + 2.0f * dot + 6.0f + text_size.x + pad, height);
  const ImVec2 min = ImGui::GetCursorScreenPos();
  ImGui::Dummy(size);
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImU32 fill = (colour & 0x00FFFFFFu) | (48u << 24);
  draw->AddRectFilled(min, ImVec2(min.x + size.x, min.y + size.y), fill, 0.5f * height);
  draw->AddRect(min, ImVec2(min.x + size.x, min.y + size.y), colour, 0.5f * height);
  draw->AddCircleFilled(ImVec2(min.x + pad + dot, min.y + 0.5f * height), dot, colour);
  draw->AddText(ImVec2(min.x + pad + 2.0f * dot + 6.0f, min.y + 0.5f * (height - text_size.y)), colours::text, text);
}

void right_aligned_text(float width, const char* text, ImU32 colour) {
  const float text_width = ImGui::CalcTextSize(text).x;
  const ImVec2 start = ImGui::GetCursorPos();
  ImGui::SetCursorPosX(start.x + std::max(0.0f, width - text_width));
  if (colour != 0)
    ImGui::TextColored(to_vec4(colour), "%s", text);
  else
    ImGui::TextUnformatted(text);
}

void same_line_if_fits(float next_width, float spacing) {
  const float right_edge = ImGui::GetWindowPos().x + ImGui::GetWindowContentRegionMax().x;
  if (ImGui::GetItemRectMax().x + spacing + next_width <= right_edge) ImGui::SameLine(0.0f, spacing);
}

bool elided_text(const std::string& text, ImU32 colour) {
  const float avail = ImGui::GetContentRegionAvail().x;
  if (ImGui::CalcTextSize(text.c_str()).x <= avail) {
    ImGui::TextColored(to_vec4(colour), "%s", text.c_str());
    return false;
  }
  static constexpr const char* kEllipsis = "\u2026";
  const float ellipsis_width = ImGui::CalcTextSize(kEllipsis).x;
  // The longest prefix that fits with the ellipsis, cut at a UTF-8 character's first byte.
  std::size_t low = 0;
  std::size_t high = text.size();
  while (low < high) {
    const std::size_t mid = (low + high + 1) / 2;
    const float width = ImGui::CalcTextSize(text.data(), text.data() + mid).x + ellipsis_width;
    if (width <= avail) low = mid;
    else high = mid - 1;
  }
  while (low > 0 && (static_cast<unsigned char>(text[low]) & 0xC0) == 0x80) --low;
  const std::string shown = text.substr(0, low) + kEllipsis;
  ImGui::TextColored(to_vec4(colour), "%s", shown.c_str());
  return true;
}

PlotResult draw_plot(const char* id, ImVec2 size, const PlotAxes& axes, std::span<const PlotSeries> series) {
  PlotResult result;
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  size.x = std::max(size.x, 40.0f);
  size.y = std::max(size.y, 40.0f);
  ImGui::InvisibleButton(id, size);
  const bool item_hovered = ImGui::IsItemHovered();
  ImDrawList* draw = ImGui::GetWindowDrawList();

  const float line = ImGui::GetTextLineHeight();
  float label_width = axes.y_label_width;
  std::vector<std::string> tick_labels;
  tick_labels.reserve(axes.y_ticks.size());
  for (double tick : axes.y_ticks) {
    tick_labels.push_back(format_tick(tick, axes.y_decimals, axes.y_unit));
    label_width = std::max(label_width, ImGui::CalcTextSize(tick_labels.back().c_str()).x);
  }
  const float left = label_width + 8.0f;
  const float top = std::floor(0.5f * line) + 1.0f;
  const float bottom = line + 6.0f;
  const float right = 6.0f;
  result.area.min = ImVec2(origin.x + left, origin.y + top);
  result.area.max = ImVec2(origin.x + size.x - right, origin.y + size.y - bottom);
  const ScreenRect& a = result.area;
  if (a.empty()) return result;

  const double x_span = axes.x_max > axes.x_min ? axes.x_max - axes.x_min : 1.0;
  const double y_span = axes.y_max > axes.y_min ? axes.y_max - axes.y_min : 1.0;
  const auto to_screen = [&](double x, double y) {
    const double u = (x - axes.x_min) / x_span;
    const double v = (y - axes.y_min) / y_span;
    return ImVec2(a.min.x + static_cast<float>(u) * a.width(), a.max.y - static_cast<float>(v) * a.height());
  };

  draw->AddRectFilled(a.min, a.max, colours::panel_bg);
  for (std::size_t i = 0; i < axes.y_ticks.size(); ++i) {
    const float y = std::round(to_screen(axes.x_min, axes.y_ticks[i]).y);
    draw->AddLine(ImVec2(a.min.x, y), ImVec2(a.max.x, y), colours::grid);
    const ImVec2 text = ImGui::CalcTextSize(tick_labels[i].c_str());
    draw->AddText(ImVec2(a.min.x - 6.0f - text.x, y - 0.5f * text.y), colours::text_dim, tick_labels[i].c_str());
  }
  const float x_label_y = a.max.y + 4.0f;
  if (axes.x_ticks.empty()) {
    const std::string x_first = format_tick(axes.x_min, 0, "");
    const std::string x_last = format_tick(axes.x_max, 0, "");
    draw->AddText(ImVec2(a.min.x, x_label_y), colours::text_dim, x_first.c_str());
    draw->AddText(ImVec2(a.max.x - ImGui::CalcTextSize(x_last.c_str()).x, x_label_y), colours::text_dim,
                  x_last.c_str());
    if (axes.x_caption != nullptr && *axes.x_caption != '\0') {
      const float caption_width = ImGui::CalcTextSize(axes.x_caption).x;
      draw->AddText(ImVec2(a.min.x + 0.5f * (a.width() - caption_width), x_label_y), colours::text_dim, axes.x_caption);
    }
  } else {
    // Labels centred on their ticks, inside the axis; one that would touch its left neighbour is
    // left out, except the last, which wins over its neighbour (the axis end must be labelled).
    struct Label {
      float x;
      std::string text;
      float width;
    };
    std::vector<Label> labels;
    for (double tick : axes.x_ticks) {
      const float x = std::round(to_screen(tick, axes.y_min).x);
      if (x < a.min.x - 0.5f || x > a.max.x + 0.5f) continue;
      draw->AddLine(ImVec2(x, a.min.y), ImVec2(x, a.max.y), colours::grid);
      std::string text = format_tick(tick, axes.x_decimals, axes.x_unit);
      const float w = ImGui::CalcTextSize(text.c_str()).x;
      labels.push_back({std::clamp(x - 0.5f * w, a.min.x, a.max.x - w), std::move(text), w});
    }
    constexpr float kGap = 6.0f;
    std::vector<const Label*> shown;
    for (const Label& label : labels) {
      const bool last = &label == &labels.back();
      while (last && !shown.empty() && shown.back()->x + shown.back()->width + kGap > label.x) shown.pop_back();
      if (shown.empty() || shown.back()->x + shown.back()->width + kGap <= label.x) shown.push_back(&label);
    }
    for (const Label* label : shown) draw->AddText(ImVec2(label->x, x_label_y), colours::text_dim, label->text.c_str());
  }

  draw->PushClipRect(a.min, a.max, true);
  std::vector<ImVec2> points;
  for (const auto& s : series) {
    const std::size_t n = std::min(s.x.size(), s.y.size());
    if (n == 0) continue;
    points.clear();
    points.reserve(n);
    for (std::size_t i = 0; i < n; ++i) points.push_back(to_screen(s.x[i], s.y[i]));
    if (s.fill != 0)
      for (std::size_t i = 1; i < n; ++i)
        draw->AddQuadFilled(points[i - 1], points[i], ImVec2(points[i].x, a.max.y), ImVec2(points[i - 1].x, a.max.y),
                            s.fill);
    if (n == 1)
      draw->AddCircleFilled(points[0], s.thickness + 1.0f, s.colour);
    else
      draw->AddPolyline(points.data(), static_cast<int>(n), s.colour, ImDrawFlags_None, s.thickness);
  }
  if (item_hovered) {
    const ImVec2 mouse = ImGui::GetIO().MousePos;
    if (a.contains(mouse)) {
      result.hovered = true;
      result.hovered_x = axes.x_min + static_cast<double>((mouse.x - a.min.x) / a.width()) * x_span;
      draw->AddLine(ImVec2(mouse.x, a.min.y), ImVec2(mouse.x, a.max.y), rgba(255, 255, 255, 70));
    }
  }
  draw->PopClipRect();
  draw->AddRect(a.min, a.max, colours::border);
  return result;
}

ScreenRect last_item_rect() { return {ImGui::GetItemRectMin(), ImGui::GetItemRectMax()}; }

void section_title(const char* text) {
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", text);
  ImGui::Separator();
}

void plot_title(const char* title, const char* detail) {
  ImGui::TextUnformatted(title);
  if (detail != nullptr && *detail != '\0') {
    ImGui::SameLine(0.0f, 6.0f);
    ImGui::TextColored(to_vec4(colours::text_dim), "%s", detail);
  }
}

}  // namespace nirslam::ui
