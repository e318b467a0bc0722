#include "ui/panels/illumination_panel.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>
#include <string>

#include <fmt/format.h>
#include <imgui.h>

#include "nirslam/photometric/exposure_sweep_calibration.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

constexpr ImU32 kDarkText = rgba(24, 22, 18);

ImU32 confidence_colour(Confidence c) {
  switch (c) {
    case Confidence::High: return colours::recommended;
    case Confidence::Medium: return colours::banner_dark;
    case Confidence::Low: return rgba(235, 120, 60);
    case Confidence::None: return colours::state_idle;
  }
  return colours::state_idle;
}

// RMS gradient in 8-bit grey levels per pixel, as `nirslam advise` prints it.
double rms_gradient_grey_levels(double gradient_energy) { return 255.0 * std::sqrt(std::max(0.0, gradient_energy)); }

// The smallest of 10, 25, 50 x 10^k giving at most `max_ticks` intervals over `span`.
double tick_step(double span, int max_ticks) {
  for (double scale = 1.0;; scale *= 10.0)
    for (double m : {1.0, 2.5, 5.0})
      if (span / (m * 10.0 * scale) <= max_ticks) return m * 10.0 * scale;
}

void dashed_line(ImDrawList* draw, ImVec2 a, ImVec2 b, ImU32 colour, float dash = 5.0f, float gap = 4.0f,
                 float thickness = 1.0f) {
  const float length = std::hypot(b.x - a.x, b.y - a.y);
  if (length <= 0.0f) return;
  const ImVec2 d((b.x - a.x) / length, (b.y - a.y) / length);
  for (float t = 0.0f; t < length; t += dash + gap) {
    const float e = std::min(t + dash, length);
    draw->AddLine(ImVec2(a.x + d.x * t, a.y + d.y * t), ImVec2(a.x + d.x * e, a.y + d.y * e), colour, thickness);
  }
}

void diamond(ImDrawList* draw, ImVec2 c, float r, ImU32 fill, ImU32 outline) {
  draw->AddQuadFilled(ImVec2(c.x, c.y - r), ImVec2(c.x + r, c.y), ImVec2(c.x, c.y + r), ImVec2(c.x - r, c.y), fill);
  draw->AddQuad(ImVec2(c.x, c.y - r - 1.0f), ImVec2(c.x + r + 1.0f, c.y), ImVec2(c.x, c.y + r + 1.0f),
                ImVec2(c.x - r - 1.0f, c.y), outline, 1.5f);
}

}  // namespace

void IlluminationPanel::draw(const Snapshot& snapshot, const CommandSink& post) {
  banner_ = plot_ = coverage_map_ = capture_button_ = response_curve_ = hold_button_ = camera_hold_rect_ =
      sweep_again_button_ = {};
  marker_.reset();
  const ImVec2 avail = ImGui::GetContentRegionAvail();
  const float recommendation_height = ImGui::GetFrameHeightWithSpacing() + ImGui::GetTextLineHeightWithSpacing();
  const bool wide = avail.x >= 720.0f;
  // In a short panel the metric tiles give way first: the banner and the wizard always show.
  const float line = ImGui::GetTextLineHeight();
  const float tiles_height = 4.0f * line + 20.0f;
  const float essentials = ImGui::GetFrameHeight() + 3.0f * ImGui::GetFrameHeightWithSpacing() + 16.0f;
  const float plot_minimum = wide ? 0.0f : 160.0f + recommendation_height;
  const bool show_tiles = avail.y >= essentials + tiles_height + plot_minimum;
  const auto left_side = [&] {
    draw_banner(snapshot);
    ImGui::Dummy(ImVec2(0.0f, 1.0f));
    if (show_tiles) {
      draw_live_metrics(snapshot);
      ImGui::Separator();
    }
    if (snapshot.illumination) draw_wizard(*snapshot.illumination, snapshot, post);
  };
  if (!snapshot.illumination) {
    left_side();
    ImGui::TextColored(to_vec4(colours::text_dim), "The power advisor starts with the worker.");
    return;
  }
  const IlluminationStatus& status = *snapshot.illumination;
  if (wide) {
    // Wide (the strip under the feed): metrics, wizard and recommendation left, the plot right.
    const float left_width = std::round(std::clamp(0.47f * avail.x, 380.0f, 520.0f));
    const ImGuiWindowFlags flags = ImGuiWindowFlags_NoScrollbar | ImGuiWindowFlags_NoScrollWithMouse |
                                   ImGuiWindowFlags_NoBackground;
    ImGui::BeginChild("##illumination_left", ImVec2(left_width, avail.y), false, flags);
    left_side();
    ImGui::EndChild();
    ImGui::SameLine(0.0f, 14.0f);
    ImGui::BeginChild("##illumination_plot", ImVec2(0.0f, avail.y), false, flags);
    draw_plot(status, ImGui::GetContentRegionAvail().y - recommendation_height - 4.0f);
    draw_recommendation(status);
    ImGui::EndChild();
    return;
  }
  // Narrow (a column): everything stacked, the plot taking what is left (if enough is left).
  left_side();
  ImGui::Separator();
  const float plot_height = ImGui::GetContentRegionAvail().y - recommendation_height - 4.0f;
  if (plot_height >= 120.0f) draw_plot(status, plot_height);
  draw_recommendation(status);
}

void IlluminationPanel::draw_banner(const Snapshot& snapshot) {
  const ExposureCheck& check = snapshot.exposure;
  ImU32 fill = colours::frame_bg;
  ImU32 text = colours::text_dim;
  std::string message = check.message;
  switch (check.verdict) {
    case ExposureVerdict::Unknown:
      message = snapshot.frame ? "No exposure verdict for this frame" : "No frame yet";
      break;
    case ExposureVerdict::Ok:
      fill = colours::banner_ok;
      text = colours::text;
      break;
    case ExposureVerdict::Clipped:
    case ExposureVerdict::ClippedAndDark:
      fill = colours::banner_clipped;
      text = rgba(255, 255, 255);
      break;
    case ExposureVerdict::Dark:
      fill = colours::banner_dark;
      text = kDarkText;
      break;
  }
  const float width = ImGui::GetContentRegionAvail().x;
  const float height = std::round(ImGui::GetFrameHeight() + 6.0f);
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  banner_.min = ImVec2(std::round(origin.x), std::round(origin.y));
  banner_.max = ImVec2(banner_.min.x + std::floor(width), banner_.min.y + height);
  ImGui::Dummy(ImVec2(width, height));
  if (ImGui::IsItemHovered() && !message.empty()) ImGui::SetTooltip("%s", message.c_str());

  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->AddRectFilled(banner_.min, banner_.max, fill, 4.0f);
  // An icon: a warning triangle for clipped or dark frames, a tick when fine.
  const float s = std::round(ImGui::GetTextLineHeight() * 0.9f);
  const ImVec2 icon(banner_.min.x + 10.0f, banner_.min.y + std::round(0.5f * (height - s)));
  const bool warning = check.clipped() || check.dark();
  if (warning) {
    draw->AddTriangleFilled(ImVec2(icon.x + 0.5f * s, icon.y), ImVec2(icon.x + s, icon.y + s), ImVec2(icon.x, icon.y + s),
                            text);
    draw->AddLine(ImVec2(icon.x + 0.5f * s, icon.y + 0.35f * s), ImVec2(icon.x + 0.5f * s, icon.y + 0.7f * s), fill, 2.0f);
    draw->AddCircleFilled(ImVec2(icon.x + 0.5f * s, icon.y + 0.84f * s), 1.2f, fill);
  } else if (check.verdict == ExposureVerdict::Ok) {
    draw->AddLine(ImVec2(icon.x + 0.1f * s, icon.y + 0.55f * s), ImVec2(icon.x + 0.4f * s, icon.y + 0.85f * s), text, 2.0f);
    draw->AddLine(ImVec2(icon.x + 0.4f * s, icon.y + 0.85f * s), ImVec2(icon.x + 0.95f * s, icon.y + 0.15f * s), text, 2.0f);
  }
  const float text_x = icon.x + s + 8.0f;
  draw->PushClipRect(banner_.min, ImVec2(banner_.max.x - 8.0f, banner_.max.y), true);
  draw->AddText(ImVec2(text_x, banner_.min.y + std::round(0.5f * (height - ImGui::GetTextLineHeight()))), text,
                message.c_str());
  draw->PopClipRect();
}

void IlluminationPanel::draw_live_metrics(const Snapshot& snapshot) {
  const bool has_frame = snapshot.frame.has_value();
  const ImageQuality& q = snapshot.quality;
  const ImageStructure& st = snapshot.structure;
  const auto value = [&](const std::string& text) { return has_frame ? text : std::string("–"); };
  struct Tile {
    const char* label;
    std::string value;
    const char* tooltip;
  };
  const std::array<Tile, 6> tiles{{
      {"Mean grey", value(fmt::format("{:.1f} %", 100.0 * q.mean)), "Mean grey value, % of full scale"},
      {"Contrast", value(fmt::format("{:.1f} %", 100.0 * q.rms_contrast)),
       "RMS contrast: standard deviation of the grey values, % of full scale"},
      {"Sharpness", value(fmt::format("{:.1f} gl/px", rms_gradient_grey_levels(st.gradient_energy))),
       "RMS gradient (forward differences) in 8-bit grey levels per pixel:\nthe square root of the gradient energy"},
      {"Corners", value(fmt::format("{}", st.feature_count)), "FAST-9 corners in the frame"},
      {"Coverage", value(fmt::format("{:.0f} %", 100.0 * st.coverage)), "Share of the grid cells holding a corner"},
      {"Evenness", value(fmt::format("{:.2f}", st.evenness)),
       "How evenly the corners spread over the grid cells:\nnormalised entropy of the corners per cell (1 = even, 0 = one cell)"},
  }};

  const ImVec2 start = ImGui::GetCursorScreenPos();
  const float avail = ImGui::GetContentRegionAvail().x;
  const float line = ImGui::GetTextLineHeight();
  const float tile_height = 2.0f * line + 4.0f;
  const float rows_height = 2.0f * tile_height + 4.0f;
  const int cols = std::max(snapshot.feature_grid.cols, 16);
  const int rows = std::max(snapshot.feature_grid.rows, 12);
  const float map_width = std::round(rows_height * static_cast<float>(cols) / static_cast<float>(rows));
  const bool show_map = avail >= 290.0f + map_width;
  const float tiles_width = show_map ? avail - map_width - 12.0f : avail;
  const float tile_width = std::floor(tiles_width / 3.0f);

  ImDrawList* draw = ImGui::GetWindowDrawList();
  const Fonts& f = fonts();
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    const ImVec2 p(start.x + static_cast<float>(i % 3) * tile_width,
                   start.y + static_cast<float>(i / 3) * (tile_height + 4.0f));
    draw->AddText(p, colours::text_dim, tiles[i].label);
    ImFont* mono = f.mono != nullptr ? f.mono : ImGui::GetFont();
    draw->AddText(mono, mono->FontSize, ImVec2(p.x, p.y + line + 2.0f), has_frame ? colours::text : colours::text_dim,
                  tiles[i].value.c_str());
    if (ImGui::IsMouseHoveringRect(p, ImVec2(p.x + tile_width, p.y + tile_height))) ImGui::SetTooltip("%s", tiles[i].tooltip);
  }
  if (show_map)
    draw_coverage_map(snapshot.feature_grid, ImVec2(start.x + avail - map_width, start.y + 2.0f),
                      ImVec2(map_width, rows_height - 4.0f));
  ImGui::Dummy(ImVec2(avail, rows_height));
}

void IlluminationPanel::draw_coverage_map(const FeatureGrid& grid, ImVec2 origin, ImVec2 size) {
  coverage_map_.min = ImVec2(std::round(origin.x), std::round(origin.y));
  coverage_map_.max = ImVec2(coverage_map_.min.x + std::round(size.x), coverage_map_.min.y + std::round(size.y));
  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->AddRectFilled(coverage_map_.min, coverage_map_.max, colours::panel_bg);
  const std::size_t cells = static_cast<std::size_t>(grid.cols) * static_cast<std::size_t>(grid.rows);
  if (grid.cols > 0 && grid.rows > 0 && grid.counts.size() == cells) {
    std::uint32_t most = 0;
    for (const auto n : grid.counts) most = std::max(most, n);
    const float cw = coverage_map_.width() / static_cast<float>(grid.cols);
    const float ch = coverage_map_.height() / static_cast<float>(grid.rows);
    const float log_most = std::log1p(static_cast<float>(most));
    for (int r = 0; r < grid.rows; ++r) {
      for (int c = 0; c < grid.cols; ++c) {
        const auto n = grid.counts[static_cast<std::size_t>(r * grid.cols + c)];
        if (n == 0) continue;
        // Log scale: a cell with one corner is visible next to one with hundreds.
        const float level = 0.25f + 0.75f * std::log1p(static_cast<float>(n)) / std::max(log_most, 1e-6f);
        const ImU32 colour = (colours::entropy & 0x00FFFFFFu) | (static_cast<ImU32>(level * 255.0f) << 24);
        const ImVec2 a(coverage_map_.min.x + c * cw, coverage_map_.min.y + r * ch);
        draw->AddRectFilled(ImVec2(std::round(a.x) + 1.0f, std::round(a.y) + 1.0f),
                            ImVec2(std::round(a.x + cw), std::round(a.y + ch)), colour);
      }
    }
  }
  draw->AddRect(coverage_map_.min, coverage_map_.max, colours::border);
  if (ImGui::IsMouseHoveringRect(coverage_map_.min, coverage_map_.max))
    ImGui::SetTooltip("FAST corners per cell of a %d x %d grid over the frame (log scale)", grid.cols, grid.rows);
}

void IlluminationPanel::draw_wizard(const IlluminationStatus& status, const Snapshot& snapshot, const CommandSink& post) {
  const bool can_post = static_cast<bool>(post);
  const SweepProgress& progress = status.progress;
  const SweepPlan& plan = status.plan;

  // Title row: the scene type on the right.
  ImGui::AlignTextToFramePadding();
  plot_title("Power sweep", fmt::format("· {}", to_string(progress.stage)).c_str());
  const SceneType* scene = status.scene();
  const float combo_width = std::min(200.0f, 0.45f * ImGui::GetContentRegionAvail().x);
  ImGui::SameLine(ImGui::GetWindowContentRegionMax().x - combo_width);
  ImGui::SetNextItemWidth(combo_width);
  if (!can_post) ImGui::BeginDisabled();
  if (ImGui::BeginCombo("##scene", scene ? scene->label.c_str() : "scene")) {
    for (std::size_t i = 0; i < status.scenes.size(); ++i) {
      const SceneType& s = status.scenes[i];
      if (ImGui::Selectable(s.label.c_str(), i == status.scene_index) && i != status.scene_index)
        post(command::Sweep{sweep_command::SelectScene{s.name}});
      if (ImGui::IsItemHovered() && s.prior)
        ImGui::SetTooltip("Prior %.0f-%.0f W (%s)", s.prior->low_w, s.prior->high_w, to_string(s.prior->basis));
    }
    ImGui::EndCombo();
  }
  if (!can_post) ImGui::EndDisabled();
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("Scene type: each keeps its own sweep; its prior stands until swept");

  const std::size_t steps = plan.powers_w.size();
  if (progress.stage != SweepStage::AwaitingPower) power_entry_step_.reset();
  switch (progress.stage) {
    case SweepStage::Idle:
    case SweepStage::Complete: {
      const double lo = steps ? *std::min_element(plan.powers_w.begin(), plan.powers_w.end()) : 0.0;
      const double hi = steps ? *std::max_element(plan.powers_w.begin(), plan.powers_w.end()) : 0.0;
      if (frames_per_power_ <= 0) frames_per_power_ = plan.frames_per_power;
      const std::string tooltip = fmt::format(
          "Step the lamp through {} powers from {:.0f} to {:.0f} W, averaging {} frames at each.\nStarting clears "
          "this scene's sweep.",
          steps, lo, hi, frames_per_power_);
      if (icon_button("start_sweep", Icon::Play, status.points.empty() ? "Start sweep" : "New sweep", can_post,
                      tooltip.c_str()))
        post(command::Sweep{sweep_command::Start{{}, frames_per_power_}});
      ImGui::SameLine();
      ImGui::SetNextItemWidth(ImGui::CalcTextSize("0000").x + 2.0f * ImGui::GetStyle().FramePadding.x);
      ImGui::InputInt("##frames", &frames_per_power_, 0, 0);
      frames_per_power_ = std::clamp(frames_per_power_, 1, 10000);
      if (ImGui::IsItemHovered()) ImGui::SetTooltip("Frames averaged at each power");
      ImGui::SameLine(0.0f, 4.0f);
      ImGui::AlignTextToFramePadding();
      ImGui::TextColored(to_vec4(colours::text_dim), "frames/power");
      const ImGuiStyle& style = ImGui::GetStyle();
      const float right = ImGui::CalcTextSize("Clear").x + ImGui::CalcTextSize("Limits").x + 4.0f * style.FramePadding.x +
                          style.ItemSpacing.x;
      ImGui::SameLine(std::max(ImGui::GetCursorPosX() + style.ItemSpacing.x, ImGui::GetWindowContentRegionMax().x - right));
      const bool can_clear = can_post && !status.points.empty();
      if (!can_clear) ImGui::BeginDisabled();
      if (ImGui::Button("Clear")) post(command::Sweep{sweep_command::Clear{}});
      if (!can_clear) ImGui::EndDisabled();
      if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled)) ImGui::SetTooltip("Drop this scene's sweep");
      ImGui::SameLine();
      if (!can_post) ImGui::BeginDisabled();
      if (ImGui::Button("Limits")) ImGui::OpenPopup("advisor_limits");
      if (!can_post) ImGui::EndDisabled();
      if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
        ImGui::SetTooltip("Plateau share %.1f %%, at most %.2f %% saturated pixels", 100.0 * status.settings.plateau_share,
                          100.0 * status.settings.max_saturated_fraction);
      draw_settings_popup(status, post);
      if (snapshot.sweep_response) draw_sweep_response(*snapshot.sweep_response, plan, post);
      break;
    }
    case SweepStage::AwaitingPower: {
      const double requested = status.requested_power_w().value_or(0.0);
      // The entry follows each new request; the operator may type the power the lamp really gives.
      if (power_entry_step_ != progress.step) {
        power_entry_w_ = requested;
        power_entry_step_ = progress.step;
      }
      ImGui::AlignTextToFramePadding();
      ImGui::Text("Lamp %zu/%zu", progress.step + 1, steps);
      if (ImGui::IsItemHovered()) ImGui::SetTooltip("Set the illuminator to this power, then press Capture");
      ImGui::SameLine();
      ImGui::SetNextItemWidth(ImGui::CalcTextSize("000.0 W").x + 2.0f * ImGui::GetStyle().FramePadding.x);
      ImGui::InputDouble("##power", &power_entry_w_, 0.0, 0.0, "%.1f W");
      power_entry_w_ = std::clamp(power_entry_w_, status.illuminator.min_power_w, status.illuminator.max_power_w);
      if (ImGui::IsItemHovered())
        ImGui::SetTooltip("The power the lamp is set to (%s, %.0f-%.0f W)", status.illuminator.description.c_str(),
                          status.illuminator.min_power_w, status.illuminator.max_power_w);
      ImGui::SameLine();
      const bool capture = icon_button("capture", Icon::Play, "Capture", can_post && snapshot.state != WorkerState::Failed,
                                       "The lamp is at this power: average the next frames");
      capture_button_ = {ImGui::GetItemRectMin(), ImGui::GetItemRectMax()};
      if (capture) post(command::Sweep{sweep_command::Capture{power_entry_w_}});
      // In a narrow strip Skip and Finish go on the next line rather than past the edge.
      const float spacing = ImGui::GetStyle().ItemSpacing.x;
      same_line_if_fits(icon_button_width("Skip"), spacing);
      if (icon_button("skip", Icon::Step, "Skip", can_post, "Leave this power out")) post(command::Sweep{sweep_command::Skip{}});
      same_line_if_fits(icon_button_width("Finish"), spacing);
      if (icon_button("finish", Icon::Stop, "Finish", can_post, "End the sweep here, keeping the powers captured"))
        post(command::Sweep{sweep_command::Finish{}});
      break;
    }
    case SweepStage::Capturing: {
      const double power = progress.capturing_w.value_or(0.0);
      const bool waiting = snapshot.state != WorkerState::Running;
      const std::string text =
          waiting ? fmt::format("{:g} W · {} / {} frames · feed paused: press Start", power, progress.frames_captured,
                                progress.frames_wanted)
          : progress.settle_remaining > 0
              ? fmt::format("{:g} W · settling, {} frames", power, progress.settle_remaining)
              : fmt::format("{:g} W · {} / {} frames", power, progress.frames_captured, progress.frames_wanted);
      const float finish_width = icon_button_width("Finish");
      const float fraction = progress.frames_wanted > 0 ? static_cast<float>(progress.frames_captured) /
                                                              static_cast<float>(progress.frames_wanted)
                                                        : 0.0f;
      ImGui::PushStyleColor(ImGuiCol_PlotHistogram, to_vec4(colours::accent));
      ImGui::ProgressBar(fraction, ImVec2(ImGui::GetContentRegionAvail().x - finish_width - 8.0f, ImGui::GetFrameHeight()),
                         text.c_str());
      ImGui::PopStyleColor();
      if (ImGui::IsItemHovered() && progress.frames_ignored > 0)
        ImGui::SetTooltip("%d frames reported another power and were not counted", progress.frames_ignored);
      ImGui::SameLine();
      if (icon_button("finish", Icon::Stop, "Finish", can_post, "End the sweep here, keeping the frames captured"))
        post(command::Sweep{sweep_command::Finish{}});
      break;
    }
  }
  const bool sweeping = progress.stage == SweepStage::AwaitingPower || progress.stage == SweepStage::Capturing;
  if (sweeping && camera_hold_) {
    const std::string text = "Camera " + *camera_hold_;
    const bool cut = elided_text(text, colours::text_dim);
    camera_hold_rect_ = last_item_rect();
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("%s%sA camera's auto exposure would follow the lamp and hide its response; the Camera tab shows "
                        "the lock.",
                        cut ? text.c_str() : "", cut ? "\n" : "");
  }
}

void IlluminationPanel::draw_sweep_response(const SweepResponse& response, const SweepPlan& plan, const CommandSink& post) {
  ImGui::AlignTextToFramePadding();
  ImGui::TextColored(to_vec4(colours::text_dim), "Response");
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip("The camera's response, fitted from the sweep's frames (the rig still, the exposure locked): the lamp's irradiance\n"
                      "follows power x exposure, other light is fitted per point. Hold writes DSO's pcalib.txt and\n"
                      "has the pipeline hold it, estimating exposures and the halo factor online.");
  ImGui::SameLine();
  switch (response.state) {
    case SweepResponse::State::Fitting:
      ImGui::AlignTextToFramePadding();
      ImGui::TextColored(to_vec4(colours::text_dim), "fitting the sweep's frames...");
      return;
    case SweepResponse::State::Failed:
      ImGui::AlignTextToFramePadding();
      ImGui::TextColored(to_vec4(colours::banner_dark), "none: %s", response.reason.c_str());
      if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", response.reason.c_str());
      return;
    case SweepResponse::State::Done:
      break;
  }
  // The fitted curve f(X) over X in [0, 1], as a small inline plot.
  const float height = ImGui::GetFrameHeight();
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const ImVec2 size(2.2f * height, height);
  ImGui::Dummy(size);
  response_curve_ = {origin, ImVec2(origin.x + size.x, origin.y + size.y)};
  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->AddRectFilled(response_curve_.min, response_curve_.max, colours::frame_bg);
  constexpr int kSegments = 24;
  ImVec2 previous = ImVec2(origin.x, origin.y + size.y);
  for (int k = 1; k <= kSegments; ++k) {
    const double X = static_cast<double>(k) / kSegments;
    const ImVec2 point(origin.x + size.x * static_cast<float>(X),
                       origin.y + size.y * (1.0f - static_cast<float>(std::clamp(response.response(X), 0.0, 1.0))));
    draw->AddLine(previous, point, colours::estimate, 1.5f);
    previous = point;
  }
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("f(X): grey over irradiance x exposure, both on [0, 1]");
  ImGui::SameLine();
  if (response.held) {
    badge("held", colours::recommended);
    hold_button_ = last_item_rect();
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", (response.folder / "pcalib.txt").string().c_str());
  } else {
    const std::string tooltip =
        fmt::format("Write pcalib.txt under {} and hold it in the pipeline",
                    response_root_.empty() ? std::string("the sessions folder") : response_root_.string());
    const bool hold = icon_button("hold_response", Icon::Fit, "Hold", static_cast<bool>(post), tooltip.c_str());
    hold_button_ = last_item_rect();
    if (hold) {
      const std::time_t now = std::time(nullptr);
      std::tm utc{};
      gmtime_r(&now, &utc);
      char name[64];
      std::strftime(name, sizeof(name), "response-%Y%m%d-%H%M%S", &utc);
      post(command::HoldSweepResponse{response_root_ / name});
    }
  }
  // The figures, short, the rest in the tooltip; when the sweep should be taken again, the button
  // takes their place (the row has no room for both) and carries them in its tooltip.
  // A share within the estimate's noise (it may come out slightly below 0) is no ambient light.
  const std::string figures = response.ambient_share_at_weakest < 0.005
                                  ? fmt::format("{:.2f} gl · no ambient light", response.residual_rms_grey)
                                  : fmt::format("{:.2f} gl · ambient {:.{}f} %", response.residual_rms_grey,
                                                100.0 * response.ambient_share_at_weakest,
                                                response.ambient_share_at_weakest < 0.1 ? 1 : 0);
  const std::string detail = fmt::format(
      "residual {:.2f} grey levels rms over {} frames at {} powers ({} points), grey levels up to {:.0f}\nambient "
      "light: {:.1f} % of the lamp's irradiance at {:g} W (median over the points){}",
      response.residual_rms_grey, response.images, response.powers_w.size(), response.points, response.highest_grey,
      100.0 * response.ambient_share_at_weakest, response.weakest_power_w,
      response.warning.empty() ? std::string() : "\n" + response.warning);
  const auto wrapped_tooltip = [](const std::string& text) {
    ImGui::BeginTooltip();
    ImGui::PushTextWrapPos(ImGui::GetFontSize() * 36.0f);
    ImGui::TextUnformatted(text.c_str());
    ImGui::PopTextWrapPos();
    ImGui::EndTooltip();
  };
  ImGui::SameLine();
  if (response.exposure_factor > 1.0 && sweep_again_exposure_ms_) {
    const std::string label = fmt::format("Sweep at {:.3g} ms", *sweep_again_exposure_ms_ * response.exposure_factor);
    ImGui::PushStyleColor(ImGuiCol_Text, to_vec4(colours::banner_dark));
    const bool again = icon_button("sweep_again", Icon::Play, label.c_str(), static_cast<bool>(post));
    ImGui::PopStyleColor();
    sweep_again_button_ = last_item_rect();
    if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
      wrapped_tooltip(fmt::format("Take the same sweep again at {:.1f}x the exposure (then the gain, where the "
                                  "camera's longest exposure is not enough), so the brightest surfaces come near grey "
                                  "{:.0f}.\n{}: {}",
                                  response.exposure_factor, kSweepTargetHighestGrey, figures, detail));
    if (again) {
      sweep_again_factor_ = response.exposure_factor;
      post(command::Sweep{sweep_command::Start{plan.powers_w, plan.frames_per_power}});
    }
    return;
  }
  ImGui::AlignTextToFramePadding();
  ImGui::TextColored(to_vec4(response.warning.empty() ? colours::text : colours::banner_dark), "%s", figures.c_str());
  if (ImGui::IsItemHovered()) wrapped_tooltip(detail);
}

void IlluminationPanel::draw_settings_popup(const IlluminationStatus& status, const CommandSink& post) {
  if (!ImGui::BeginPopup("advisor_limits")) {
    share_entry_ = static_cast<float>(100.0 * status.settings.plateau_share);
    clip_entry_ = static_cast<float>(100.0 * status.settings.max_saturated_fraction);
    return;
  }
  ImGui::TextColored(to_vec4(colours::text_dim), "The advisor recommends the lowest power whose fitted entropy\n"
                                                 "reaches this share of its plateau, within the clipping limit.");
  ImGui::SetNextItemWidth(220.0f);
  ImGui::SliderFloat("plateau share", &share_entry_, 80.0f, 99.5f, "%.1f %%");
  ImGui::SetNextItemWidth(220.0f);
  ImGui::SliderFloat("saturated pixels at most", &clip_entry_, 0.0f, 10.0f, "%.2f %%");
  if (ImGui::Button("Apply") && post) {
    AdvisorSettings settings = status.settings;
    settings.plateau_share = share_entry_ / 100.0;
    settings.max_saturated_fraction = clip_entry_ / 100.0;
    post(command::Sweep{sweep_command::SetSettings{settings}});
    ImGui::CloseCurrentPopup();
  }
  ImGui::EndPopup();
}

void IlluminationPanel::draw_plot(const IlluminationStatus& status, float height) {
  const Recommendation& rec = status.recommendation;
  const float title_top = ImGui::GetCursorScreenPos().y;
  // Title and legend; in a narrow plot the detail, then the legend, give way.
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const std::string detail = rec.fit ? fmt::format("· {} powers fitted", rec.points_fitted) : std::string();
  const float line_h = ImGui::GetTextLineHeight();
  const float legend_width = ImGui::CalcTextSize("measured").x + ImGui::CalcTextSize("fit").x +
                             ImGui::CalcTextSize("recommended").x + 3.0f * 17.0f + 2.0f * 8.0f;
  const float title_width = ImGui::CalcTextSize("Entropy vs power").x;
  const float avail_width = ImGui::GetContentRegionAvail().x;
  const bool show_legend = title_width + legend_width + 12.0f <= avail_width;
  const bool show_detail =
      !detail.empty() && title_width + 6.0f + ImGui::CalcTextSize(detail.c_str()).x + 12.0f +
                                 (show_legend ? legend_width : 0.0f) <= avail_width;
  plot_title("Entropy vs power", show_detail ? detail.c_str() : "");
  if (show_legend) {
    ImGui::SameLine();
    ImGui::SetCursorPosX(std::max(ImGui::GetCursorPosX(), ImGui::GetWindowContentRegionMax().x - legend_width));
    const auto swatch = [&](int kind, ImU32 colour, const char* label) {
      const ImVec2 p = ImGui::GetCursorScreenPos();
      const ImVec2 c(p.x + 6.0f, p.y + 0.5f * line_h);
      if (kind == 0) draw->AddCircleFilled(c, 3.5f, colour);
      if (kind == 1) draw->AddLine(ImVec2(c.x - 6.0f, c.y), ImVec2(c.x + 6.0f, c.y), colour, 2.0f);
      if (kind == 2) diamond(draw, c, 4.5f, colour, colours::panel_bg);
      ImGui::Dummy(ImVec2(13.0f, line_h));
      ImGui::SameLine(0.0f, 4.0f);
      ImGui::TextColored(to_vec4(colours::text_dim), "%s", label);
    };
    swatch(0, colours::sweep_point, "measured");
    ImGui::SameLine(0.0f, 8.0f);
    swatch(1, colours::fit_curve, "fit");
    ImGui::SameLine(0.0f, 8.0f);
    swatch(2, colours::recommended, "recommended");
  }

  double x_max = status.illuminator.max_power_w;
  for (const SweepPoint& p : status.points) x_max = std::max(x_max, p.power_w);
  if (rec.source != RecommendationSource::None) x_max = std::max(x_max, rec.power_w);
  if (rec.high_w) x_max = std::max(x_max, *rec.high_w);
  const double x_min = std::min(0.0, status.illuminator.min_power_w);
  PlotAxes axes;
  axes.x_min = x_min;
  axes.x_max = x_max > x_min ? x_max : x_min + 1.0;
  const int max_ticks = std::clamp(static_cast<int>(ImGui::GetContentRegionAvail().x / 80.0f), 2, 10);
  const double step = tick_step(axes.x_max - axes.x_min, max_ticks);
  for (double t = std::ceil(axes.x_min / step) * step; t <= axes.x_max + 1e-9; t += step) axes.x_ticks.push_back(t);
  axes.x_unit = " W";
  axes.y_min = 0.0;
  axes.y_max = 8.0;
  axes.y_ticks = {0.0, 2.0, 4.0, 6.0, 8.0};
  axes.y_unit = " bits";

  curve_x_.clear();
  curve_y_.clear();
  if (rec.fit) {
    constexpr int kSamples = 160;
    for (int i = 0; i <= kSamples; ++i) {
      const double x = axes.x_min + (axes.x_max - axes.x_min) * i / kSamples;
      curve_x_.push_back(x);
      curve_y_.push_back(std::clamp(rec.fit->curve(x), 0.0, 8.0));
    }
  }
  const std::array<PlotSeries, 1> series{PlotSeries{curve_x_, curve_y_, colours::fit_curve, 2.0f, 0}};
  const float width = ImGui::GetContentRegionAvail().x;
  const float plot_height = height - (ImGui::GetCursorScreenPos().y - title_top);
  const PlotResult result = ui::draw_plot("##entropy_power", ImVec2(width, std::max(plot_height, 60.0f)), axes, series);
  plot_ = result.area;
  if (plot_.empty()) return;

  const auto to_screen = [&](double x, double y) {
    return ImVec2(plot_.min.x + static_cast<float>((x - axes.x_min) / (axes.x_max - axes.x_min)) * plot_.width(),
                  plot_.max.y - static_cast<float>((y - axes.y_min) / (axes.y_max - axes.y_min)) * plot_.height());
  };
  draw->PushClipRect(plot_.min, plot_.max, true);
  // A prior: its power range as a band, the suggested power as a line.
  if (rec.source == RecommendationSource::Prior && rec.low_w && rec.high_w) {
    const float x0 = to_screen(*rec.low_w, 0.0).x;
    const float x1 = to_screen(*rec.high_w, 0.0).x;
    draw->AddRectFilled(ImVec2(x0, plot_.min.y), ImVec2(x1, plot_.max.y), colours::recommended_band);
    const char* label = "prior range";
    draw->AddText(ImVec2(x0 + 4.0f, plot_.min.y + 3.0f), colours::recommended, label);
  }
  // The plateau share the recommendation aims at.
  if (rec.fit) {
    const double target = status.settings.plateau_share * rec.fit->curve.h_max_bits;
    const float y = std::round(to_screen(0.0, target).y);
    dashed_line(draw, ImVec2(plot_.min.x, y), ImVec2(plot_.max.x, y), (colours::fit_curve & 0x00FFFFFFu) | (140u << 24));
    const std::string label = fmt::format("{:.0f} % of plateau", 100.0 * status.settings.plateau_share);
    const ImVec2 size = ImGui::CalcTextSize(label.c_str());
    draw->AddText(ImVec2(plot_.max.x - size.x - 4.0f, y + 2.0f), colours::text_dim, label.c_str());
  }
  // Measured points: mean and one standard deviation; points left out of the fit drawn hollow.
  for (const SweepPoint& p : status.points) {
    const ImVec2 c = to_screen(p.power_w, p.entropy_bits.mean);
    const double sd = p.entropy_bits.stddev();
    if (sd > 0.0) {
      const float y0 = to_screen(0.0, p.entropy_bits.mean - sd).y;
      const float y1 = to_screen(0.0, p.entropy_bits.mean + sd).y;
      draw->AddLine(ImVec2(c.x, y0), ImVec2(c.x, y1), colours::sweep_point, 1.0f);
      draw->AddLine(ImVec2(c.x - 3.0f, y0), ImVec2(c.x + 3.0f, y0), colours::sweep_point, 1.0f);
      draw->AddLine(ImVec2(c.x - 3.0f, y1), ImVec2(c.x + 3.0f, y1), colours::sweep_point, 1.0f);
    }
    const bool excluded = std::any_of(rec.excluded_powers_w.begin(), rec.excluded_powers_w.end(),
                                      [&](double w) { return std::abs(w - p.power_w) <= SweepRecord::kSamePowerW; });
    if (excluded)
      draw->AddCircle(c, 4.0f, colours::sweep_point, 0, 1.5f);
    else
      draw->AddCircleFilled(c, 4.0f, colours::sweep_point);
  }
  // The recommended point: on the curve for a sweep, on the power axis for a prior.
  if (rec.source == RecommendationSource::Sweep) {
    const ImVec2 m = to_screen(rec.power_w, std::clamp(rec.expected_entropy_bits, 0.0, 8.0));
    dashed_line(draw, ImVec2(m.x, plot_.max.y), ImVec2(m.x, m.y + 8.0f), colours::recommended, 4.0f, 3.0f, 1.5f);
    diamond(draw, m, 7.0f, colours::recommended, colours::panel_bg);
    marker_ = m;
  } else if (rec.source == RecommendationSource::Prior) {
    const ImVec2 m = to_screen(rec.power_w, 0.0);
    dashed_line(draw, ImVec2(m.x, plot_.max.y), ImVec2(m.x, plot_.min.y + 18.0f), colours::recommended, 4.0f, 3.0f, 1.5f);
    diamond(draw, ImVec2(m.x, m.y - 8.0f), 7.0f, colours::recommended, colours::panel_bg);
    marker_ = ImVec2(m.x, m.y - 8.0f);
  }
  draw->PopClipRect();

  // The point under the mouse.
  if (result.hovered) {
    const ImVec2 mouse = ImGui::GetIO().MousePos;
    const SweepPoint* nearest = nullptr;
    float best = 12.0f;
    for (const SweepPoint& p : status.points) {
      const ImVec2 c = to_screen(p.power_w, p.entropy_bits.mean);
      const float d = std::hypot(c.x - mouse.x, c.y - mouse.y);
      if (d < best) {
        best = d;
        nearest = &p;
      }
    }
    if (nearest != nullptr)
      ImGui::SetTooltip("%.1f W · %d frames\nentropy %.3f ± %.3f bits\nsaturated %.2f %% · black %.1f %%\n"
                        "mean grey %.1f %% · contrast %.1f %%\n%.0f corners · coverage %.0f %%",
                        nearest->power_w, nearest->frames, nearest->entropy_bits.mean, nearest->entropy_bits.stddev(),
                        100.0 * nearest->saturated_fraction.mean, 100.0 * nearest->black_fraction.mean,
                        100.0 * nearest->mean.mean, 100.0 * nearest->rms_contrast.mean, nearest->feature_count.mean,
                        100.0 * nearest->coverage.mean);
  }
}

void IlluminationPanel::draw_recommendation(const IlluminationStatus& status) {
  const Recommendation& rec = status.recommendation;
  const ImVec2 start = ImGui::GetCursorScreenPos();
  ImGui::AlignTextToFramePadding();
  ImGui::TextColored(to_vec4(colours::text_dim), "Recommended");
  ImGui::SameLine();
  ImGui::AlignTextToFramePadding();
  if (rec.source == RecommendationSource::None) {
    ImGui::TextColored(to_vec4(colours::text_dim), "–");
  } else {
    ImGui::TextColored(to_vec4(colours::recommended), "%.0f W", rec.power_w);
  }
  ImGui::SameLine(0.0f, 10.0f);
  const std::string badge_text =
      rec.source == RecommendationSource::None
          ? std::string("sweep needed")
          : fmt::format("{}{} · {} confidence", to_string(rec.source), rec.extrapolated ? ", extrapolated" : "",
                        to_string(rec.confidence));
  badge(badge_text.c_str(), confidence_colour(rec.confidence));

  std::string detail;
  switch (rec.source) {
    case RecommendationSource::Sweep:
      detail = fmt::format("{:.2f} bits, {:.1f} % of plateau{}{}", rec.expected_entropy_bits, 100.0 * rec.expected_share,
                           rec.expected_saturated_fraction
                               ? fmt::format(" · {:.2f} % saturated", 100.0 * *rec.expected_saturated_fraction)
                               : std::string(),
                           rec.clipping_limited ? " · clipping limit binds"
                           : rec.extrapolated  ? fmt::format(" · sweep stopped at {:.0f} W", rec.highest_swept_w)
                                               : std::string(" · plateau reached"));
      break;
    case RecommendationSource::Prior: {
      const SceneType* scene = status.scene();
      const bool paper = scene && scene->prior && scene->prior->basis == PriorBasis::Paper;
      detail = fmt::format("{} prior {:.0f}-{:.0f} W ({}) · sweep to measure", scene ? scene->label : std::string("scene"),
                           rec.low_w.value_or(0.0), rec.high_w.value_or(0.0),
                           paper ? "paper" : "project assumption");
      break;
    }
    case RecommendationSource::None:
      detail = rec.reasons.empty() ? std::string("no prior and no sweep") : rec.reasons.front();
      break;
  }
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", detail.c_str());
  const ImVec2 end(start.x + ImGui::GetContentRegionAvail().x, ImGui::GetCursorScreenPos().y);
  if (ImGui::IsMouseHoveringRect(start, end) && !rec.reasons.empty()) {
    std::string reasons;
    for (const std::string& r : rec.reasons) reasons += "• " + r + "\n";
    ImGui::SetTooltip("%s", reasons.c_str());
  }
}

}  // namespace nirslam::ui
