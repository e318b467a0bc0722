#pragma once

#include <imgui.h>

namespace nirslam::ui {

// Packs a colour the way ImGui's IM_COL32 does (A in the top byte, then B, G, R), without the
// macro's C-style casts.
constexpr ImU32 rgba(unsigned r, unsigned g, unsigned b, unsigned a = 255) {
  return (a << 24) | (b << 16) | (g << 8) | r;
}
ImVec4 to_vec4(ImU32 colour);

// The palette. Panels draw with these names, and the headless tests look for them in screenshots.
namespace colours {
inline constexpr ImU32 window_bg = rgba(30, 33, 38);
inline constexpr ImU32 panel_bg = rgba(24, 26, 30);
inline constexpr ImU32 frame_bg = rgba(44, 48, 56);
inline constexpr ImU32 border = rgba(58, 63, 72);
inline constexpr ImU32 text = rgba(222, 225, 230);
inline constexpr ImU32 text_dim = rgba(140, 147, 158);
inline constexpr ImU32 accent = rgba(70, 150, 230);
inline constexpr ImU32 feed_bg = rgba(16, 17, 20);
inline constexpr ImU32 overlay_bg = rgba(10, 11, 13, 190);
inline constexpr ImU32 grid = rgba(60, 65, 74);
inline constexpr ImU32 entropy = rgba(56, 204, 180);       // gauge fill and history line
inline constexpr ImU32 entropy_fill = rgba(56, 204, 180, 40);
inline constexpr ImU32 histogram = rgba(150, 160, 176);
inline constexpr ImU32 saturated = rgba(235, 64, 52);       // clipped high: plots and feed overlay
inline constexpr ImU32 black = rgba(56, 110, 245);          // clipped low
inline constexpr ImU32 sweep_point = rgba(222, 225, 230);      // measured entropy per power
inline constexpr ImU32 fit_curve = rgba(245, 158, 50);          // fitted entropy(power) curve
inline constexpr ImU32 recommended = rgba(132, 226, 92);        // recommended power: marker, line, text
inline constexpr ImU32 recommended_band = rgba(132, 226, 92, 34);  // a prior's power range
inline constexpr ImU32 banner_ok = rgba(38, 110, 70);
inline constexpr ImU32 banner_clipped = rgba(205, 48, 40);      // the frame is clipped: lower the power
inline constexpr ImU32 banner_dark = rgba(226, 160, 40);        // the frame is too dark: raise the power
inline constexpr ImU32 estimate = rgba(245, 158, 50);            // photometric estimates: curves, exposure
inline constexpr ImU32 ground_truth = rgba(190, 196, 206);       // the true curve / value, when known
inline constexpr ImU32 keyframe_mark = rgba(70, 150, 230);      // frames handed to the back end
inline constexpr ImU32 unmeasured_band = rgba(150, 157, 168, 36);  // where a curve is a continuation, not data
inline constexpr ImU32 state_running = rgba(72, 196, 112);
inline constexpr ImU32 state_paused = rgba(236, 176, 58);
inline constexpr ImU32 state_idle = rgba(120, 127, 138);
inline constexpr ImU32 state_finished = rgba(90, 150, 240);
inline constexpr ImU32 state_failed = rgba(235, 64, 52);
}  // namespace colours

struct Fonts {
  ImFont* regular = nullptr;  // body text
  ImFont* large = nullptr;    // big readouts (entropy value)
  ImFont* mono = nullptr;     // numbers that change every frame, so they do not jitter
  bool scalable = false;      // true when a TrueType font was found (else ImGui's built-in font)
};

// Loads the fonts into the current context's atlas (before the renderer builds it): DejaVu Sans
// when installed (or $NIRSLAM_FONT), else ImGui's built-in bitmap font. `scale` multiplies sizes.
const Fonts& load_fonts(float scale = 1.0f);
const Fonts& fonts();

// Colours and metrics of the project's dark theme, scaled for HiDPI by `scale`.
void apply_style(float scale = 1.0f);

}  // namespace nirslam::ui
