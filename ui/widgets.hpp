#pragma once

#include <algorithm>
#include <array>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include <imgui.h>

namespace nirslam::ui {

// An axis-aligned rectangle in ImGui screen coordinates (pixels, origin top-left).
struct ScreenRect {
  ImVec2 min{0.0f, 0.0f};
  ImVec2 max{0.0f, 0.0f};
  float width() const { return max.x - min.x; }
  float height() const { return max.y - min.y; }
  ImVec2 size() const { return ImVec2(width(), height()); }
  ImVec2 centre() const { return ImVec2(0.5f * (min.x + max.x), 0.5f * (min.y + max.y)); }
  bool empty() const { return width() <= 0.0f || height() <= 0.0f; }
  bool contains(ImVec2 p) const { return p.x >= min.x && p.x < max.x && p.y >= min.y && p.y < max.y; }
};

// A label/value pair in an overlay table; the value is drawn in `colour` (0 = theme text).
struct OverlayRow {
  std::string label;
  std::string value;
  ImU32 colour = 0;
};

enum class Corner { TopLeft, TopRight, BottomLeft, BottomRight };

// A translucent box of aligned label/value rows drawn over an image, anchored at a corner of
// `area` with a margin. Returns the box.
ScreenRect draw_overlay_table(ImDrawList* draw, const ScreenRect& area, Corner corner,
                              const std::vector<OverlayRow>& rows);

enum class Icon { Play, Pause, Step, Stop, Fit };

// A button with a drawn icon and a label (no "##" suffixes: the id is separate); disabled buttons are greyed and return false. The
// tooltip (if any) shows on hover.
bool icon_button(const char* id, Icon icon, const char* label, bool enabled, const char* tooltip = nullptr);
// The width icon_button takes with this label (to lay out a row before drawing it).
float icon_button_width(const char* label);

// The last ImGui item's rectangle (for the screenshot tests' geometry).
ScreenRect last_item_rect();

// A dim caption over a separator, heading a column of a panel.
void section_title(const char* text);

// A plot's title with a dim detail after it on the same line (none when `detail` is empty).
void plot_title(const char* title, const char* detail);

// Copies `text` into a fixed ImGui text buffer, cut to fit, always terminated.
template <std::size_t N>
void copy_into(std::array<char, N>& buffer, const std::string& text) {
  const std::size_t n = std::min(text.size(), N - 1);
  std::memcpy(buffer.data(), text.data(), n);
  buffer[n] = '\0';
}

// A small filled rounded badge with text, e.g. the worker state.
void badge(const char* text, ImU32 colour);

// Text that keeps its place when the value changes width (numbers): right-aligned in a box.
void right_aligned_text(float width, const char* text, ImU32 colour = 0);

// For a row of status items: the next item goes on the same line, `spacing` after the last one,
// when `next_width` still fits before the window's right edge, else on a new line.
void same_line_if_fits(float next_width, float spacing);

// Text cut with an ellipsis to the width left on the line, so it never runs past the window's
// edge. Returns whether it was cut (the caller's tooltip then shows the whole text).
bool elided_text(const std::string& text, ImU32 colour);

// One line of a plot.
struct PlotSeries {
  std::span<const double> x;
  std::span<const double> y;
  ImU32 colour = 0;
  float thickness = 2.0f;
  ImU32 fill = 0;  // area under the line, when non-zero
};

struct PlotAxes {
  double x_min = 0.0;
  double x_max = 1.0;
  double y_min = 0.0;
  double y_max = 1.0;
  std::vector<double> y_ticks;  // values with a grid line and a label
  int y_decimals = 0;
  const char* y_unit = "";      // appended to the y tick labels, e.g. " bits"
  float y_label_width = 0.0f;   // at least this wide, so stacked plots line up
  const char* x_caption = "";   // under the x axis, e.g. "frame"
  // Values with a vertical grid line and a label, instead of the two end labels and the caption
  // (put the unit into x_unit).
  std::vector<double> x_ticks;
  int x_decimals = 0;
  const char* x_unit = "";      // appended to the x tick labels, e.g. " W"
};

struct PlotResult {
  ScreenRect area;        // the data area inside the axes
  bool hovered = false;
  double hovered_x = 0.0; // data x under the mouse, when hovered
};

// A line plot with a labelled y axis, grid, x range labels and caption, in `size` pixels at the
// cursor. X ticks: both ends of the range. No allocation per frame beyond ImGui's draw lists.
PlotResult draw_plot(const char* id, ImVec2 size, const PlotAxes& axes, std::span<const PlotSeries> series);

}  // namespace nirslam::ui
