#include "ui/panels/photometric_panel.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include <fmt/format.h>
#include <imgui.h>

#include "ui/colour_maps.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

constexpr float kSwatchWidth = 20.0f;
constexpr float kLegendSpacing = 12.0f;

float legend_width(bool with_truth, bool with_unmeasured) {
  const auto entry = [](const char* text) { return kSwatchWidth + 2.0f + ImGui::CalcTextSize(text).x; };
  float width = entry("estimate");
  if (with_truth) width += kLegendSpacing + entry("ground truth");
  if (with_unmeasured) width += kLegendSpacing + entry("not measured");
  return width;
}

// One item for the status row's layout (a group), legend_width() wide.
void legend(bool with_truth, bool with_unmeasured) {
  ImGui::BeginGroup();
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const auto swatch = [&](ImU32 colour, const char* text) {
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float y = p.y + 0.5f * ImGui::GetTextLineHeight();
    draw->AddLine(ImVec2(p.x, y), ImVec2(p.x + 16.0f, y), colour, 2.5f);
    ImGui::Dummy(ImVec2(kSwatchWidth, ImGui::GetTextLineHeight()));
    ImGui::SameLine(0.0f, 2.0f);
    ImGui::TextColored(to_vec4(colours::text_dim), "%s", text);
  };
  swatch(colours::estimate, "estimate");
  if (with_truth) {
    ImGui::SameLine(0.0f, kLegendSpacing);
    swatch(colours::ground_truth, "ground truth");
  }
  if (with_unmeasured) {
    ImGui::SameLine(0.0f, kLegendSpacing);
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float h = ImGui::GetTextLineHeight();
    draw->AddRectFilled(ImVec2(p.x, p.y + 0.15f * h), ImVec2(p.x + 16.0f, p.y + 0.85f * h), colours::unmeasured_band);
    ImGui::Dummy(ImVec2(kSwatchWidth, h));
    ImGui::SameLine(0.0f, 2.0f);
    ImGui::TextColored(to_vec4(colours::text_dim), "not measured");
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("Outside the grey range and beyond the radius the back end's samples reach (1st-99th\n"
                        "percentile), the curves are the model's continuation, not data");
  }
  ImGui::EndGroup();
}

// Shades the parts of a plot's x range outside [measured_lo, measured_hi]: there the curve is the
// model's continuation. Nothing when the range is unknown (empty).
void shade_unmeasured(const ScreenRect& area, double x_min, double x_max, double measured_lo, double measured_hi) {
  if (area.empty() || !(measured_hi > measured_lo) || !(x_max > x_min)) return;
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const auto x_of = [&](double x) {
    return area.min.x + static_cast<float>(std::clamp((x - x_min) / (x_max - x_min), 0.0, 1.0)) * area.width();
  };
  const float lo = x_of(measured_lo), hi = x_of(measured_hi);
  if (lo > area.min.x + 0.5f) draw->AddRectFilled(area.min, ImVec2(lo, area.max.y), colours::unmeasured_band);
  if (hi < area.max.x - 0.5f) draw->AddRectFilled(ImVec2(hi, area.min.y), area.max, colours::unmeasured_band);
}

// Ticks at 0, 1/n, ... of a range, so every small plot reads the same way.
std::vector<double> even_ticks(double lo, double hi, int n) {
  std::vector<double> ticks;
  for (int i = 0; i <= n; ++i) ticks.push_back(lo + (hi - lo) * i / n);
  return ticks;
}

std::vector<double> quarter_ticks(double lo, double hi) { return even_ticks(lo, hi, 4); }

}  // namespace

void PhotometricPanel::update_curves(const PhotometricView& view) {
  if (cached_for_ == &view && cached_version_ == view.model_version) return;
  cached_for_ = &view;
  cached_version_ = view.model_version;
  x_unit_.resize(kCurveSamples);
  x_grey_.resize(kCurveSamples);
  response_.resize(kCurveSamples);
  inverse_.resize(kCurveSamples);
  vignette_.resize(kCurveSamples);
  response_true_.clear();
  inverse_true_.clear();
  vignette_true_.clear();
  const bool range_known = view.grey_high > view.grey_low;
  measured_irradiance_lo_ = range_known ? view.response.inverse(view.grey_low / 255.0) : 0.0;
  measured_irradiance_hi_ = range_known ? view.response.inverse(view.grey_high / 255.0) : 0.0;
  for (int i = 0; i < kCurveSamples; ++i) {
    const double t = static_cast<double>(i) / (kCurveSamples - 1);
    x_unit_[i] = t;
    x_grey_[i] = 255.0 * t;
    response_[i] = 255.0 * view.response(t);
    inverse_[i] = 255.0 * view.response.inverse(t);
    vignette_[i] = view.vignette(t);
    if (view.true_response) {
      response_true_.push_back(255.0 * (*view.true_response)(t));
      inverse_true_.push_back(255.0 * view.true_response->inverse(t));
    }
    // Under the lamp the estimate is the halo factor (lens times beam): compare it with that.
    if (view.true_halo) vignette_true_.push_back((*view.true_halo)(t));
    else if (view.true_vignette) vignette_true_.push_back((*view.true_vignette)(t));
  }
}

void PhotometricPanel::draw(const Snapshot& snapshot) {
  response_plot_ = inverse_plot_ = vignette_plot_ = vignette_map_ = exposure_plot_ = range_advice_ = {};
  const PhotometricView* view = snapshot.photometric.get();
  if (view == nullptr || !view->enabled) {
    const ImVec2 avail = ImGui::GetContentRegionAvail();
    const ImVec2 origin = ImGui::GetCursorScreenPos();
    const char* line1 = "Photometric calibration off";
    const char* line2 = "Choose a pipeline mode with online calibration to estimate response, vignette and exposure";
    const ImVec2 s1 = ImGui::CalcTextSize(line1);
    const ImVec2 s2 = ImGui::CalcTextSize(line2);
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const ImVec2 c(origin.x + 0.5f * avail.x, origin.y + 0.5f * avail.y);
    draw->AddText(ImVec2(c.x - 0.5f * s1.x, c.y - s1.y - 2.0f), colours::text, line1);
    draw->AddText(ImVec2(c.x - 0.5f * s2.x, c.y + 2.0f), colours::text_dim, line2);
    return;
  }
  update_curves(*view);
  draw_status(*view);
  const float avail = ImGui::GetContentRegionAvail().y;
  const float curves = std::floor(0.56f * avail);
  draw_curves(*view, curves);
  draw_exposure(*view, ImGui::GetContentRegionAvail().y);
}

void PhotometricPanel::draw_status(const PhotometricView& view) {
  const bool has_estimate = view.model_version > 0;
  const ImU32 colour = view.converged ? colours::state_running : has_estimate ? colours::state_paused : colours::state_idle;
  badge(view.converged ? "converged" : has_estimate ? "optimising" : "waiting", colour);
  ImGui::SameLine();
  if (has_estimate)
    ImGui::Text("model v%d · %d keyframes · %d points · %d iterations", view.model_version, view.keyframes, view.points,
                view.iterations);
  else
    ImGui::TextColored(to_vec4(colours::text_dim), "%s", view.status.empty() ? "no back-end estimate yet" : view.status.c_str());
  // Items flow onto a new line where the window is too narrow; the long texts (the ambiguity, the
  // lamp offset's reason) are cut with an ellipsis, whole in their tooltips.
  constexpr float kGap = 16.0f;
  const bool with_truth = view.true_response.has_value() || view.true_vignette.has_value();
  const bool with_unmeasured = view.grey_high > view.grey_low || view.radius_high > 0.0;
  same_line_if_fits(legend_width(with_truth, with_unmeasured), kGap);
  legend(with_truth, with_unmeasured);
  if (view.range_advice) {
    // The response above the brightest samples is the model's continuation, and with it the
    // irradiance scale: the operator can fix that by showing the camera brighter images.
    const GreyRangeAdvice& advice = *view.range_advice;
    const std::string text = fmt::format("response measured to grey {:.0f}: {:.1f}x brighter images would measure the rest",
                                         advice.highest_grey, advice.exposure_factor);
    same_line_if_fits(ImGui::CalcTextSize(text.c_str()).x, kGap);  // whole, on a line of its own if need be
    elided_text(text, colours::state_paused);
    range_advice_ = last_item_rect();
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("%s.\nWays there: a longer exposure or more gain for a while (auto exposure locked, Camera tab), a\n"
                        "brighter view, or the response from an illuminator sweep (Illumination tab), held.",
                        describe(advice).c_str());
  }
  if (view.lamp_not_modelled) {
    const char* text = "lamp on, not modelled";
    same_line_if_fits(ImGui::CalcTextSize(text).x, kGap);
    ImGui::TextColored(to_vec4(colours::state_paused), "%s", text);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("The frames report the co-located lamp on. Calibration alone assumes that a point's radiance\n"
                        "is constant, but under the lamp it changes with the point's distance, and the fit bends the\n"
                        "response (a plateau) and the vignette to explain that. The mode 'calibrated + lamp' models\n"
                        "the lamp's distance factor.");
  }
  if (!view.lamp_term.empty()) {
    same_line_if_fits(ImGui::CalcTextSize(view.lamp_term.c_str()).x, kGap);
    elided_text(view.lamp_term, colours::text_dim);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("%s\nUnder the co-located lamp a point's radiance changes with its distance: the calibration takes\n"
                        "the distances from the odometry's points and divides out (d_ref/d)^2 (P/P_ref)",
                        view.lamp_term.c_str());
  }
  if (!view.ambiguity.empty()) {
    // Beside the rest when a readable part of it fits there.
    same_line_if_fits(std::min(ImGui::CalcTextSize(view.ambiguity.c_str()).x, 240.0f), kGap);
    elided_text(view.ambiguity, colours::text_dim);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("%s\nThe response is only known up to f^gamma and a scale: this is how the estimate fixes them",
                        view.ambiguity.c_str());
  }
  // The beam first: short, so the offset's longer "why not" is what a narrow window cuts.
  bool lamp_line_started = false;
  if (!view.lamp_beam.empty()) {
    elided_text(view.lamp_beam, colours::text_dim);
    lamp_line_started = true;
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("%s\nThe halo factor divided by the lens vignetting (calibration.lens_vignette): the lamp's beam\n"
                        "pattern, fitted by cos(alpha)^m",
                        view.lamp_beam.c_str());
  }
  if (!view.lamp_offset.empty()) {
    if (lamp_line_started) same_line_if_fits(std::min(ImGui::CalcTextSize(view.lamp_offset.c_str()).x, 240.0f), kGap);
    elided_text(view.lamp_offset, colours::text_dim);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("Where the lamp sits relative to the camera centre (camera axes, the odometry's units), from the\n"
                        "brightness of the window's points across the recent keyframes:\n%s", view.lamp_offset.c_str());
  }
}

void PhotometricPanel::draw_curves(const PhotometricView& view, float height) {
  const float spacing = ImGui::GetStyle().ItemSpacing.x;
  const float width = ImGui::GetContentRegionAvail().x;
  const float map_width = std::min(std::floor(0.22f * width), std::floor((height - ImGui::GetTextLineHeightWithSpacing()) * 4.0f / 3.0f));
  const float plot_width = std::floor((width - map_width - 3.0f * spacing) / 3.0f);
  const float title = ImGui::GetTextLineHeightWithSpacing();
  const float plot_height = std::max(40.0f, height - title);

  const auto cell = [&](const char* caption, auto body) {
    ImGui::BeginGroup();
    ImGui::TextColored(to_vec4(colours::text_dim), "%s", caption);
    body();
    ImGui::EndGroup();
  };

  // Estimate over truth (when known) on shared x samples.
  const ImVec2 plot_size(plot_width, plot_height);
  const auto curve = [&](const char* id, const PlotAxes& axes, const std::vector<double>& x, const std::vector<double>& estimate,
                         const std::vector<double>& truth) {
    std::array<PlotSeries, 2> series{PlotSeries{truth.empty() ? std::span<const double>() : x, truth, colours::ground_truth, 1.5f},
                                     PlotSeries{x, estimate, colours::estimate, 2.0f}};
    return draw_plot(id, plot_size, axes, series).area;
  };
  PlotAxes grey_axes;
  grey_axes.y_max = 255.0;
  grey_axes.y_ticks = quarter_ticks(0.0, 255.0);
  grey_axes.y_label_width = ImGui::CalcTextSize("255").x;

  cell("Response f", [&] {
    PlotAxes axes = grey_axes;
    axes.x_caption = "irradiance (0..1)";
    response_plot_ = curve("##response", axes, x_unit_, response_, response_true_);
    shade_unmeasured(response_plot_, 0.0, 1.0, measured_irradiance_lo_, measured_irradiance_hi_);
  });
  ImGui::SameLine();
  cell("Inverse response G (pcalib)", [&] {
    PlotAxes axes = grey_axes;
    axes.x_max = 255.0;
    axes.x_caption = "grey level";
    inverse_plot_ = curve("##inverse", axes, x_grey_, inverse_, inverse_true_);
    shade_unmeasured(inverse_plot_, 0.0, 255.0, view.grey_low, view.grey_high);
  });
  ImGui::SameLine();
  // Under the co-located lamp its beam B falls off towards the rim as the lens vignetting V does,
  // in every frame alike, so what the calibration estimates is their product.
  const bool lamp_lit = view.true_halo || view.lamp_not_modelled || !view.lamp_term.empty();
  cell(lamp_lit ? "Halo factor V(r) B(r)" : "Vignette V(r)", [&] {
    double lo = *std::min_element(vignette_.begin(), vignette_.end());
    for (double v : vignette_true_) lo = std::min(lo, v);
    lo = std::max(0.0, std::floor(lo * 10.0 - 0.5) / 10.0);
    PlotAxes axes;
    axes.y_min = lo;
    axes.y_max = 1.0 + 0.02;
    axes.y_ticks = quarter_ticks(lo, 1.0);
    axes.y_decimals = 2;
    axes.x_caption = "radius (corner = 1)";
    vignette_plot_ = curve("##vignette", axes, x_unit_, vignette_, vignette_true_);
    if (lamp_lit && ImGui::IsItemHovered())
      ImGui::SetTooltip("The co-located lamp lights the scene: its beam B falls off towards the rim as the lens\n"
                        "vignetting V does, and in every frame alike, so the estimate is their product, the halo factor.%s",
                        view.true_halo ? "\nThe ground truth drawn is the lens vignetting times the simulator's beam." : "");
    if (view.radius_high > 0.0) shade_unmeasured(vignette_plot_, 0.0, 1.0, 0.0, view.radius_high);
  });
  ImGui::SameLine();
  cell("Vignette map", [&] { draw_vignette_map(view, ImVec2(map_width, plot_height)); });
}

void PhotometricPanel::draw_vignette_map(const PhotometricView& view, ImVec2 size) {
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  ImGui::Dummy(size);
  // 4:3 map centred in the cell, over the image as the camera sees it.
  const float w = std::min(size.x, std::floor(size.y * 4.0f / 3.0f));
  const float h = std::floor(w * 3.0f / 4.0f);
  vignette_map_.min = ImVec2(origin.x + std::floor(0.5f * (size.x - w)), origin.y);
  vignette_map_.max = ImVec2(vignette_map_.min.x + w, vignette_map_.min.y + h);
  ImDrawList* draw = ImGui::GetWindowDrawList();
  constexpr int kCols = 32;
  constexpr int kRows = 24;
  const double corner = view.vignette(1.0);
  const double lo = std::min(corner, 0.999);
  for (int row = 0; row < kRows; ++row)
    for (int col = 0; col < kCols; ++col) {
      const double r = VignetteModel::radius(col + 0.5, row + 0.5, kCols + 1, kRows + 1);
      const double v = view.vignette(r);
      const float t = static_cast<float>((v - lo) / (1.0 - lo));
      const ImVec2 a(vignette_map_.min.x + w * col / kCols, vignette_map_.min.y + h * row / kRows);
      const ImVec2 b(vignette_map_.min.x + w * (col + 1) / kCols + 0.5f, vignette_map_.min.y + h * (row + 1) / kRows + 0.5f);
      draw->AddRectFilled(a, b, heat_colour(0.15f + 0.85f * t));
      if (view.radius_high > 0.0 && r > view.radius_high) draw->AddRectFilled(a, b, colours::unmeasured_band);
    }
  if (view.radius_high > 0.0) {  // the edge of the measured disc (radius over the half-diagonal)
    draw->PushClipRect(vignette_map_.min, vignette_map_.max, true);
    draw->AddCircle(vignette_map_.centre(), static_cast<float>(view.radius_high) * 0.5f * std::hypot(w, h),
                    colours::text_dim, 96, 1.0f);
    draw->PopClipRect();
  }
  draw->AddRect(vignette_map_.min, vignette_map_.max, colours::border);
  const std::string label = fmt::format("corners {:.2f}", corner);
  const ImVec2 text = ImGui::CalcTextSize(label.c_str());
  if (text.x + 8.0f < w) {
    const ImVec2 p(vignette_map_.min.x + 4.0f, vignette_map_.max.y - text.y - 3.0f);
    draw->AddRectFilled(ImVec2(p.x - 2.0f, p.y - 1.0f), ImVec2(p.x + text.x + 2.0f, p.y + text.y + 1.0f), colours::overlay_bg);
    draw->AddText(p, colours::text, label.c_str());
  }
}

void PhotometricPanel::draw_exposure(const PhotometricView& view, float height) {
  frames_.clear();
  exposure_.clear();
  reference_.clear();
  reference_frames_.clear();
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const ExposurePoint& p : view.exposures) {
    if (std::isfinite(p.estimated)) {
      frames_.push_back(static_cast<double>(p.frame_index));
      exposure_.push_back(p.estimated);
      lo = std::min(lo, static_cast<double>(p.estimated));
      hi = std::max(hi, static_cast<double>(p.estimated));
    }
    if (std::isfinite(p.reference)) {
      reference_frames_.push_back(static_cast<double>(p.frame_index));
      reference_.push_back(p.reference);
      lo = std::min(lo, static_cast<double>(p.reference));
      hi = std::max(hi, static_cast<double>(p.reference));
    }
  }
  const std::string scale = view.exposure_scale_frames > 0
                                ? fmt::format("; estimate x{:.3f}, median over {} frames", view.exposure_scale,
                                              view.exposure_scale_frames)
                                : std::string();
  const std::string caption = fmt::format("Exposure ({}{}){}", view.exposure_unit, scale,
                                          view.exposure_status.empty() ? "" : " · last frame: " + view.exposure_status);
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", caption.c_str());
  height -= ImGui::GetTextLineHeightWithSpacing();
  if (!std::isfinite(lo)) {
    lo = 0.0;
    hi = 1.0;
  }
  const double margin = std::max(0.05 * (hi - lo), 1e-3 * std::abs(hi));
  PlotAxes axes;
  axes.y_min = std::max(0.0, lo - margin);
  axes.y_max = hi + margin;
  // A short plot gets fewer labels, so they never touch.
  axes.y_ticks = even_ticks(axes.y_min, axes.y_max, height < 4.0f * ImGui::GetTextLineHeight() * 2.0f ? 2 : 4);
  axes.y_decimals = axes.y_max < 1.0 ? 3 : axes.y_max < 10.0 ? 2 : 1;
  const double first = view.exposures.empty() ? 0.0 : static_cast<double>(view.exposures.front().frame_index);
  const double last = view.exposures.empty() ? 1.0 : static_cast<double>(view.exposures.back().frame_index);
  axes.x_min = first;
  axes.x_max = std::max(last, first + 1.0);
  axes.x_caption = "frame";
  std::array<PlotSeries, 2> series{PlotSeries{reference_frames_, reference_, colours::ground_truth, 1.5f},
                                   PlotSeries{frames_, exposure_, colours::estimate, 2.0f}};
  const float width = ImGui::GetContentRegionAvail().x;
  exposure_plot_ = draw_plot("##exposure", ImVec2(width, std::max(50.0f, height - 2.0f)), axes, series).area;
  // Keyframes: ticks along the bottom of the plot.
  if (!exposure_plot_.empty()) {
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const double span = axes.x_max - axes.x_min;
    for (const ExposurePoint& p : view.exposures) {
      if (!p.keyframe) continue;
      const float x = exposure_plot_.min.x + static_cast<float>((p.frame_index - axes.x_min) / span) * exposure_plot_.width();
      draw->AddLine(ImVec2(x, exposure_plot_.max.y - 6.0f), ImVec2(x, exposure_plot_.max.y - 1.0f), colours::keyframe_mark, 1.5f);
    }
  }
}

}  // namespace nirslam::ui
