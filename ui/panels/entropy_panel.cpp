#include "ui/panels/entropy_panel.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <fmt/format.h>
#include <imgui.h>

#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

// The smallest of 1, 2, 5 x 10^k percent at or above `value` (at least 1 %).
double nice_percent_ceiling(double value) {
  double step = 1.0;
  while (true) {
    for (double m : {1.0, 2.0, 5.0})
      if (m * step >= value) return std::min(100.0, m * step);
    step *= 10.0;
    if (step > 100.0) return 100.0;
  }
}

std::string percent_text(double fraction) {
  const double percent = 100.0 * fraction;
  if (percent > 0.0 && percent < 0.01) return "< 0.01 %";
  return fmt::format("{:.2f} %", percent);
}

}  // namespace

void EntropyPanel::draw(const Snapshot& snapshot) {
  gauge_ = fill_ = entropy_plot_ = clipping_plot_ = histogram_rect_ = {};
  draw_readout(snapshot);
  draw_gauge(snapshot.frame ? snapshot.quality.entropy_bits : 0.0);
  ImGui::Dummy(ImVec2(0.0f, 4.0f));
  draw_clipping_bars(snapshot.quality);
  ImGui::Dummy(ImVec2(0.0f, 2.0f));
  ImGui::Separator();
  // In a short window the optional sections give way to the entropy history, which always stays.
  const float line = ImGui::GetFrameHeightWithSpacing();
  const float history_min = 2.0f * line + 120.0f;
  const float clipping_min = line + 90.0f;
  const float histogram_height = line + ImGui::GetFrameHeight() * 3.6f + ImGui::GetTextLineHeight() + 12.0f;
  const float avail = ImGui::GetContentRegionAvail().y;
  clipping_shown_ = show_clipping_plot && avail >= history_min + clipping_min;
  histogram_shown_ = show_histogram && avail >= history_min + (clipping_shown_ ? clipping_min : 0.0f) + histogram_height;
  if (histogram_shown_) {
    draw_histogram(snapshot);
    ImGui::Separator();
  }
  draw_history(snapshot);
}

void EntropyPanel::draw_readout(const Snapshot& snapshot) {
  const bool has_frame = snapshot.frame.has_value();
  ImGui::TextColored(to_vec4(colours::text_dim), "Information entropy of the current frame");
  const Fonts& f = fonts();
  const std::string value = has_frame ? fmt::format("{:.2f}", snapshot.quality.entropy_bits) : std::string("–");
  if (f.large != nullptr) ImGui::PushFont(f.large);
  ImGui::TextColored(to_vec4(has_frame ? colours::text : colours::text_dim), "%s", value.c_str());
  const float large_height = ImGui::GetTextLineHeight();
  if (f.large != nullptr) ImGui::PopFont();
  // The unit on the large number's baseline.
  ImGui::SameLine(0.0f, 6.0f);
  ImGui::SetCursorPosY(ImGui::GetCursorPosY() + large_height - ImGui::GetTextLineHeight() - 3.0f);
  ImGui::TextUnformatted("bits");
  ImGui::SameLine();
  const std::string detail = has_frame ? fmt::format("frame #{} · max 8 bits (256 bins)", snapshot.frame->index)
                                       : std::string("no frame yet");
  const float detail_width = ImGui::CalcTextSize(detail.c_str()).x;
  ImGui::SetCursorPosX(std::max(ImGui::GetCursorPosX(), ImGui::GetWindowContentRegionMax().x - detail_width));
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", detail.c_str());
}

void EntropyPanel::draw_gauge(double bits) {
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const float width = ImGui::GetContentRegionAvail().x;
  const float height = std::round(ImGui::GetFrameHeight() * 0.9f);
  const ImVec2 min = ImGui::GetCursorScreenPos();
  gauge_.min = ImVec2(std::round(min.x), std::round(min.y));
  gauge_.max = ImVec2(gauge_.min.x + std::floor(width), gauge_.min.y + height);
  const float line = ImGui::GetTextLineHeight();
  ImGui::Dummy(ImVec2(width, height + 6.0f + line));

  const double clamped = std::clamp(bits, 0.0, kMaxBits);
  fill_ = gauge_;
  fill_.max.x = gauge_.min.x + std::round(static_cast<float>(clamped / kMaxBits) * gauge_.width());
  draw->AddRectFilled(gauge_.min, gauge_.max, colours::frame_bg, 3.0f);
  if (fill_.width() > 0.0f) draw->AddRectFilled(fill_.min, fill_.max, colours::entropy, 3.0f);
  draw->AddRect(gauge_.min, gauge_.max, colours::border, 3.0f);

  for (int i = 0; i <= static_cast<int>(kMaxBits); ++i) {
    const float x = std::round(gauge_.min.x + static_cast<float>(i / kMaxBits) * (gauge_.width() - 1.0f));
    draw->AddLine(ImVec2(x, gauge_.max.y), ImVec2(x, gauge_.max.y + 4.0f), colours::text_dim);
    const std::string label = std::to_string(i);
    const float w = ImGui::CalcTextSize(label.c_str()).x;
    const float lx = std::clamp(x - 0.5f * w, gauge_.min.x, gauge_.max.x - w);
    draw->AddText(ImVec2(lx, gauge_.max.y + 5.0f), colours::text_dim, label.c_str());
  }
}

void EntropyPanel::draw_clipping_bars(const ImageQuality& quality) {
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const float label_width = ImGui::CalcTextSize("Saturated").x + 12.0f;
  const float value_width = ImGui::CalcTextSize("100.00 %").x + 8.0f;
  const auto bar = [&](const char* label, double fraction, ImU32 colour, const char* tooltip) {
    ImGui::AlignTextToFramePadding();
    ImGui::TextUnformatted(label);
    ImGui::SameLine(label_width + ImGui::GetStyle().WindowPadding.x);
    const float width = std::max(20.0f, ImGui::GetContentRegionAvail().x - value_width);
    const float height = std::round(ImGui::GetFrameHeight() * 0.5f);
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float y = std::round(p.y + 0.5f * (ImGui::GetFrameHeight() - height));
    ImGui::Dummy(ImVec2(width, ImGui::GetFrameHeight()));
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", tooltip);
    const float filled = static_cast<float>(std::clamp(fraction / kClippingBarRange, 0.0, 1.0)) * width;
    draw->AddRectFilled(ImVec2(p.x, y), ImVec2(p.x + width, y + height), colours::frame_bg, 2.0f);
    if (filled > 0.0f) draw->AddRectFilled(ImVec2(p.x, y), ImVec2(p.x + std::max(filled, 2.0f), y + height), colour, 2.0f);
    ImGui::SameLine(0.0f, 8.0f);
    ImGui::AlignTextToFramePadding();
    right_aligned_text(value_width - 8.0f, percent_text(fraction).c_str());
  };
  bar("Saturated", quality.saturated_fraction, colours::saturated,
      "Pixels at the top code of the bit depth.\nThe bar spans 0 to 10 % of the frame.");
  bar("Black", quality.black_fraction, colours::black, "Pixels at code 0.\nThe bar spans 0 to 10 % of the frame.");
}

void EntropyPanel::draw_histogram(const Snapshot& snapshot) {
  const GreyHistogram& histogram = snapshot.histogram;
  const Frame* frame = snapshot.frame && !snapshot.frame->image.empty() ? &*snapshot.frame : nullptr;
  plot_title("Histogram", "· 256 bins, log count");

  const float width = ImGui::GetContentRegionAvail().x;
  const float height = std::round(ImGui::GetFrameHeight() * 3.6f);
  const float line = ImGui::GetTextLineHeight();
  const float label_width = ImGui::CalcTextSize("0.00 bits").x + 8.0f;  // lines up with the plots below
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  ImGui::Dummy(ImVec2(width, height + line + 4.0f));
  ScreenRect& a = histogram_rect_;
  a.min = ImVec2(std::round(origin.x + label_width), std::round(origin.y));
  a.max = ImVec2(std::round(origin.x + width - 6.0f), std::round(origin.y + height));
  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->AddRectFilled(a.min, a.max, colours::panel_bg);

  std::uint64_t tallest = 0;
  for (const auto count : histogram) tallest = std::max(tallest, count);
  if (tallest > 0) {
    const double log_tallest = std::log1p(static_cast<double>(tallest));
    const float bin_width = a.width() / 256.0f;
    for (int i = 0; i < 256; ++i) {
      const auto count = histogram[static_cast<std::size_t>(i)];
      if (count == 0) continue;
      const float h = static_cast<float>(std::log1p(static_cast<double>(count)) / log_tallest) * (a.height() - 2.0f);
      const float x0 = a.min.x + static_cast<float>(i) * bin_width;
      draw->AddRectFilled(ImVec2(x0, a.max.y - h), ImVec2(x0 + std::max(bin_width, 1.0f), a.max.y), colours::histogram);
    }
  }
  draw->AddRect(a.min, a.max, colours::border);
  const std::string top = frame != nullptr ? std::to_string(frame->max_value()) : std::string("255");
  draw->AddText(ImVec2(a.min.x, a.max.y + 3.0f), colours::text_dim, "0");
  draw->AddText(ImVec2(a.max.x - ImGui::CalcTextSize(top.c_str()).x, a.max.y + 3.0f), colours::text_dim, top.c_str());
  const char* caption = "grey level";
  draw->AddText(ImVec2(a.min.x + 0.5f * (a.width() - ImGui::CalcTextSize(caption).x), a.max.y + 3.0f), colours::text_dim,
                caption);
  if (ImGui::IsItemHovered() && tallest > 0) {
    const ImVec2 mouse = ImGui::GetIO().MousePos;
    if (a.contains(mouse)) {
      const int bin = std::clamp(static_cast<int>((mouse.x - a.min.x) / a.width() * 256.0f), 0, 255);
      ImGui::SetTooltip("Bin %d: %llu pixels", bin,
                        static_cast<unsigned long long>(histogram[static_cast<std::size_t>(bin)]));
    }
  }
}

void EntropyPanel::draw_history(const Snapshot& snapshot) {
  const auto& history = snapshot.quality_history;
  // The plots span `history_frames`, or the whole sequence when it is shorter.
  std::size_t span = static_cast<std::size_t>(std::max(history_frames, 2));
  if (snapshot.source.frame_count && *snapshot.source.frame_count >= 2) span = std::min(span, *snapshot.source.frame_count);
  const std::size_t count = std::min(history.size(), span);
  const std::size_t first = history.size() - count;
  x_.clear();
  index_.clear();
  entropy_.clear();
  saturated_.clear();
  black_.clear();
  double sum = 0.0;
  double lowest = kMaxBits;
  double highest = 0.0;
  double clip_max = 0.0;
  for (std::size_t i = first; i < history.size(); ++i) {
    const auto& s = history[i];
    // x counts processed frames (1 = the first of this run): it keeps increasing when a source
    // loops or is rewound, where frame indices start again. The tooltip names the frame index.
    x_.push_back(static_cast<double>(snapshot.frames_processed - static_cast<std::int64_t>(history.size() - 1 - i)));
    index_.push_back(s.frame_index);
    entropy_.push_back(s.quality.entropy_bits);
    saturated_.push_back(100.0 * s.quality.saturated_fraction);
    black_.push_back(100.0 * s.quality.black_fraction);
    sum += s.quality.entropy_bits;
    lowest = std::min(lowest, s.quality.entropy_bits);
    highest = std::max(highest, s.quality.entropy_bits);
    clip_max = std::max({clip_max, saturated_.back(), black_.back()});
  }

  const bool whole_sequence = snapshot.source.frame_count && span == *snapshot.source.frame_count;
  const std::string span_text = whole_sequence ? fmt::format("· all {} frames", span) : fmt::format("· last {} frames", span);
  plot_title("Entropy history", span_text.c_str());
  ImGui::SameLine();
  const float checkbox_width = ImGui::CalcTextSize("Auto scale").x + ImGui::GetFrameHeight() +
                               ImGui::GetStyle().ItemInnerSpacing.x;
  ImGui::SetCursorPosX(std::max(ImGui::GetCursorPosX(), ImGui::GetWindowContentRegionMax().x - checkbox_width));
  // The title row is text-high; the checkbox is frame-high: keep it on the text's baseline.
  ImGui::PushStyleVar(ImGuiStyleVar_FramePadding, ImVec2(ImGui::GetStyle().FramePadding.x, 0.0f));
  ImGui::Checkbox("Auto scale", &auto_scale);
  ImGui::PopStyleVar();
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip("Fit the entropy axis to the values shown instead of 0 to 8 bits");
  const std::string stats = count > 0 ? fmt::format("mean {:.2f} · min {:.2f} · max {:.2f} bits",
                                                    sum / static_cast<double>(count), lowest, highest)
                                      : std::string("no frames yet");
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", stats.c_str());

  PlotAxes axes;
  axes.y_label_width = ImGui::CalcTextSize("0.00 bits").x;
  const double last_x = count > 0 ? x_.back() : 0.0;
  axes.x_min = count > 0 ? std::max(x_.front(), last_x - static_cast<double>(span - 1)) : 1.0;
  axes.x_max = axes.x_min + static_cast<double>(span - 1);
  axes.x_caption = "frames processed";

  const float title_height = ImGui::GetFrameHeightWithSpacing();
  const float avail = ImGui::GetContentRegionAvail().y;
  const float entropy_height =
      clipping_shown_ ? std::floor((avail - title_height - ImGui::GetStyle().ItemSpacing.y) * 0.58f) : avail;
  const float width = ImGui::GetContentRegionAvail().x;

  PlotAxes entropy_axes = axes;
  entropy_axes.y_min = 0.0;
  entropy_axes.y_max = kMaxBits;
  entropy_axes.y_ticks = {0.0, 2.0, 4.0, 6.0, 8.0};
  if (auto_scale && count > 0) {
    // Half-bit bounds around the values shown, at least one bit tall.
    double lo = std::max(0.0, std::floor((lowest - 0.05) * 2.0) / 2.0);
    double hi = std::min(kMaxBits, std::ceil((highest + 0.05) * 2.0) / 2.0);
    if (hi - lo < 1.0) {
      const double mid = 0.5 * (lo + hi);
      lo = std::max(0.0, mid - 0.5);
      hi = std::min(kMaxBits, lo + 1.0);
    }
    const double range = hi - lo;
    const double step = range <= 1.0 ? 0.25 : range <= 2.0 ? 0.5 : range <= 4.0 ? 1.0 : 2.0;
    entropy_axes.y_min = lo;
    entropy_axes.y_max = hi;
    entropy_axes.y_ticks.clear();
    for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9; t += step) entropy_axes.y_ticks.push_back(t);
    entropy_axes.y_decimals = step < 0.5 ? 2 : step < 1.0 ? 1 : 0;
  }
  entropy_axes.y_unit = " bits";
  const std::array<PlotSeries, 1> entropy_series{
      PlotSeries{x_, entropy_, colours::entropy, 2.0f, colours::entropy_fill}};
  const PlotResult entropy_plot = draw_plot("##entropy_history", ImVec2(width, entropy_height), entropy_axes, entropy_series);
  entropy_plot_ = entropy_plot.area;

  PlotResult clipping_plot;
  if (clipping_shown_) {
    plot_title("Clipped pixels", "· % of the frame");
    ImGui::SameLine();
    const float legend_width = ImGui::CalcTextSize("saturated").x + ImGui::CalcTextSize("black").x + 60.0f;
    ImGui::SetCursorPosX(std::max(ImGui::GetCursorPosX(), ImGui::GetWindowContentRegionMax().x - legend_width));
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const float swatch = std::round(ImGui::GetTextLineHeight() * 0.7f);
    for (const auto& [label, colour] : {std::pair{"saturated", colours::saturated}, std::pair{"black", colours::black}}) {
      const ImVec2 p = ImGui::GetCursorScreenPos();
      const float y = std::round(p.y + 0.5f * (ImGui::GetTextLineHeight() - swatch));
      draw->AddRectFilled(ImVec2(p.x, y), ImVec2(p.x + swatch, y + swatch), colour, 2.0f);
      ImGui::Dummy(ImVec2(swatch, ImGui::GetTextLineHeight()));
      ImGui::SameLine(0.0f, 4.0f);
      ImGui::TextColored(to_vec4(colours::text_dim), "%s", label);
      ImGui::SameLine(0.0f, 12.0f);
    }
    ImGui::NewLine();
    PlotAxes clip_axes = axes;
    clip_axes.y_min = 0.0;
    clip_axes.y_max = nice_percent_ceiling(clip_max);
    clip_axes.y_ticks = {0.0, 0.5 * clip_axes.y_max, clip_axes.y_max};
    clip_axes.y_decimals = std::fmod(0.5 * clip_axes.y_max, 1.0) != 0.0 ? 1 : 0;
    clip_axes.y_unit = " %";
    const std::array<PlotSeries, 2> clip_series{PlotSeries{x_, saturated_, colours::saturated, 2.0f, 0},
                                                PlotSeries{x_, black_, colours::black, 2.0f, 0}};
    const float clip_height = std::max(40.0f, ImGui::GetContentRegionAvail().y);
    clipping_plot = draw_plot("##clipping_history", ImVec2(width, clip_height), clip_axes, clip_series);
    clipping_plot_ = clipping_plot.area;
  }

  // Tooltip with the sample under the mouse in either plot.
  const PlotResult& hovered = entropy_plot.hovered ? entropy_plot : clipping_plot;
  if (hovered.hovered && !x_.empty()) {
    const auto it = std::lower_bound(x_.begin(), x_.end(), hovered.hovered_x);
    std::size_t i = static_cast<std::size_t>(it - x_.begin());
    if (i == x_.size() || (i > 0 && hovered.hovered_x - x_[i - 1] < x_[i] - hovered.hovered_x)) i = i > 0 ? i - 1 : 0;
    ImGui::SetTooltip("Frame #%lld (processed %.0f)\nEntropy %.2f bits\nSaturated %.2f %%\nBlack %.2f %%",
                      static_cast<long long>(index_[i]), x_[i], entropy_[i],
                      saturated_[i], black_[i]);
  }
}

}  // namespace nirslam::ui
