#include "ui/panels/camera_panel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>

#include <fmt/format.h>
#include <imgui.h>

#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

// The slider's track alone (the item rectangle also holds its label): `width` from CalcItemWidth.
ScreenRect last_frame_rect(float width) {
  const ImVec2 min = ImGui::GetItemRectMin();
  return {min, ImVec2(min.x + width, ImGui::GetItemRectMax().y)};
}

// A slider value on the device's step from the minimum, inside the range.
double on_step(double value, const ControlRange& range) {
  double v = std::clamp(value, range.minimum, range.maximum);
  if (range.step > 0.0) v = range.minimum + std::round((v - range.minimum) / range.step) * range.step;
  return std::clamp(v, range.minimum, range.maximum);
}

std::string state_text(const CameraState& s, const std::string& control_error) {
  std::string text = fmt::format("{} {}", to_string(s.connection), s.device);
  if (!control_error.empty()) return text + ": " + control_error;
  if (!s.error.empty()) return text + ": " + s.error;
  if (!s.message.empty()) return text + ": " + s.message;
  return text;
}

}  // namespace

unsigned CameraPanel::banner_colour(const CameraState& state, bool control_error) {
  if (control_error || state.connection == CameraConnection::Failed) return colours::state_failed;
  switch (state.connection) {
    case CameraConnection::Streaming: return colours::banner_ok;
    case CameraConnection::Unplugged:
    case CameraConnection::Reconnecting: return colours::banner_dark;
    default: return colours::state_idle;
  }
}

template <typename F>
void CameraPanel::apply(F&& change) {
  try {
    change();
    control_error_.clear();
  } catch (const std::exception& e) {
    control_error_ = e.what();
  }
}

void CameraPanel::draw(const CameraState& state, CameraControls* controls) {
  banner_ = exposure_slider_ = gain_slider_ = auto_exposure_ = lock_ = {};
  draw_banner(state);
  ImGui::Spacing();
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", state.card.empty() ? "camera" : state.card.c_str());
  ImGui::Text("%s, %d bit%s", state.format.empty() ? "no format yet" : state.format.c_str(), state.bit_depth,
              state.stereo_side_by_side ? ", side-by-side stereo (left view to SLAM)" : "");
  draw_counters(state);
  ImGui::Separator();
  draw_exposure(state, controls);
  draw_rate(state, controls);
}

void CameraPanel::draw_banner(const CameraState& state) {
  const std::string text = state_text(state, control_error_);
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const float width = std::max(1.0f, ImGui::GetContentRegionAvail().x);
  const float wrap = width - 16.0f;
  const ImVec2 text_size = ImGui::CalcTextSize(text.c_str(), nullptr, false, wrap);
  const float height = std::max(ImGui::GetFrameHeight() + 8.0f, text_size.y + 12.0f);
  banner_.min = ImVec2(std::round(origin.x), std::round(origin.y));
  banner_.max = ImVec2(banner_.min.x + std::floor(width), banner_.min.y + height);
  draw->AddRectFilled(banner_.min, banner_.max, banner_colour(state, !control_error_.empty()), 4.0f);
  draw->AddText(nullptr, 0.0f, ImVec2(banner_.min.x + 8.0f, banner_.min.y + std::round(0.5f * (height - text_size.y))),
                colours::text, text.c_str(), nullptr, wrap);
  ImGui::Dummy(ImVec2(width, height));
}

void CameraPanel::draw_counters(const CameraState& s) {
  ImGui::Text("%lld frames  %.1f fps", static_cast<long long>(s.frames_captured), s.measured_fps);
  ImGui::SameLine();
  const std::int64_t dropped = s.frames_dropped_by_driver + s.frames_dropped_by_queue;
  ImGui::TextColored(to_vec4(dropped > 0 ? colours::banner_dark : colours::text_dim), "dropped %lld (driver %lld, queue %lld)",
                     static_cast<long long>(dropped), static_cast<long long>(s.frames_dropped_by_driver),
                     static_cast<long long>(s.frames_dropped_by_queue));
  if (s.exposure_in_effect_ms || s.gain_in_effect)
    ImGui::Text("in effect: %s, gain %s",
                s.exposure_in_effect_ms ? fmt::format("{:.2f} ms", *s.exposure_in_effect_ms).c_str() : "-",
                s.gain_in_effect ? fmt::format("{:g} ({:.2f}x)", *s.gain_in_effect, *s.gain_in_effect / s.gain_unity).c_str() : "-");
}

void CameraPanel::draw_exposure(const CameraState& s, CameraControls* controls) {
  const bool live = controls != nullptr && s.connection == CameraConnection::Streaming;

  bool locked = s.locked;
  ImGui::BeginDisabled(!live);
  if (ImGui::Checkbox("Lock exposure and gain", &locked)) apply([&] { controls->set_locked(locked); });
  lock_ = last_item_rect();
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("Hold exposure and gain so the photometric calibration sees known, fixed values");
  bool automatic = s.auto_exposure;
  ImGui::BeginDisabled(!s.auto_exposure_available || s.locked);
  if (ImGui::Checkbox("Auto exposure", &automatic)) apply([&] { controls->set_auto_exposure(automatic); });
  auto_exposure_ = last_item_rect();
  ImGui::EndDisabled();

  const float label_width = ImGui::CalcTextSize("Exposure").x + ImGui::GetStyle().ItemInnerSpacing.x + 8.0f;
  ImGui::PushItemWidth(std::max(80.0f, ImGui::GetContentRegionAvail().x - label_width));
  if (s.exposure_ms.available) {
    const ControlRange& r = s.exposure_ms;
    const double shown = s.exposure_in_effect_ms.value_or(r.default_value);
    float value = exposure_entry_ms_ >= 0.0f ? exposure_entry_ms_ : static_cast<float>(shown);
    ImGui::BeginDisabled(s.auto_exposure || s.locked);
    const std::string format = fmt::format("%.{}f ms", r.step < 0.1 ? 2 : 1);
    const float track = ImGui::CalcItemWidth();
    const bool changed = ImGui::SliderFloat("Exposure", &value, static_cast<float>(r.minimum), static_cast<float>(r.maximum),
                                            format.c_str(), ImGuiSliderFlags_Logarithmic | ImGuiSliderFlags_AlwaysClamp);
    exposure_slider_ = last_frame_rect(track);
    if (ImGui::IsItemActive()) exposure_entry_ms_ = value;
    if (changed) {
      const double ms = on_step(value, r);
      apply([&] { controls->set_exposure_ms(ms); });
    }
    if (ImGui::IsItemDeactivated()) exposure_entry_ms_ = -1.0f;
    ImGui::EndDisabled();
    if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
      ImGui::SetTooltip("%.2f..%.1f ms in steps of %.2f ms", r.minimum, r.maximum, r.step);
  } else {
    ImGui::TextColored(to_vec4(colours::text_dim), "no exposure control");
  }
  if (s.gain.available) {
    const ControlRange& r = s.gain;
    float value = gain_entry_ >= 0.0f ? gain_entry_ : static_cast<float>(s.gain_in_effect.value_or(r.default_value));
    ImGui::BeginDisabled(s.locked);
    const float track = ImGui::CalcItemWidth();
    const bool changed = ImGui::SliderFloat("Gain", &value, static_cast<float>(r.minimum), static_cast<float>(r.maximum), "%.0f",
                                            ImGuiSliderFlags_AlwaysClamp);
    gain_slider_ = last_frame_rect(track);
    if (ImGui::IsItemActive()) gain_entry_ = value;
    if (changed) {
      const double gain = on_step(value, r);
      apply([&] { controls->set_gain(gain); });
    }
    if (ImGui::IsItemDeactivated()) gain_entry_ = -1.0f;
    ImGui::EndDisabled();
  } else {
    ImGui::TextColored(to_vec4(colours::text_dim), "no gain control");
  }
  ImGui::PopItemWidth();
  ImGui::EndDisabled();
}

void CameraPanel::draw_rate(const CameraState& s, CameraControls* controls) {
  const bool live = controls != nullptr && s.connection == CameraConnection::Streaming;
  ImGui::BeginDisabled(!live || s.rates_fps.empty());
  const std::string current = s.fps > 0.0 ? fmt::format("{:g} fps", s.fps) : std::string("device rate");
  ImGui::PushItemWidth(std::min(160.0f, ImGui::GetContentRegionAvail().x));
  if (ImGui::BeginCombo("Frame rate", current.c_str())) {
    for (const double rate : s.rates_fps) {
      const std::string label = fmt::format("{:g} fps", rate);
      if (ImGui::Selectable(label.c_str(), std::abs(rate - s.fps) < 1e-6)) apply([&] { controls->set_frame_rate(rate); });
    }
    ImGui::EndCombo();
  }
  ImGui::PopItemWidth();
  ImGui::EndDisabled();
  if (s.buffer_count > 0) {
    ImGui::SameLine();
    ImGui::TextColored(to_vec4(colours::text_dim), "%d driver buffers", s.buffer_count);
  }
}

}  // namespace nirslam::ui
