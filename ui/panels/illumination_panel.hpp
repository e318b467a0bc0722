#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <imgui.h>

#include "nirslam/worker/snapshot.hpp"
#include "ui/command_sink.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// Illumination: what the operator needs to choose the illuminator power.
//   - a banner with the live verdict on the frame (clipped: red, too dark: amber, fine: green),
//   - live metrics (mean grey, RMS contrast, sharpness, power, FAST corners, coverage, evenness)
//     and a map of the corners per grid cell,
//   - the sweep wizard: scene type, start, "set the lamp to P W" with the power to confirm,
//     capture progress, skip, finish, and what the camera's exposure is held at for the sweep,
//   - the entropy-vs-power plot: measured points (mean, one standard deviation), the fitted
//     saturating curve, the plateau share, and the recommended power (or the prior's range),
//   - the recommendation with its confidence; its reasons in the tooltip,
//   - after a sweep, the camera response fitted from its frames (snapshot.sweep_response: the
//     curve, residual, ambient share, or why there is none) and Hold, which writes it under the
//     response folder and has the pipeline hold it (command::HoldSweepResponse); when its images
//     stopped short of the top and a camera was held for it, "Sweep at N ms" to take it again.
// It reads snapshot.illumination, snapshot.quality/structure/exposure; the wizard's state lives in
// the worker (SweepRecorder), the panel only posts command::Sweep and keeps what is being typed.
class IlluminationPanel {
public:
  // Draws into the current ImGui window, filling it. Without a sink the controls are disabled.
  void draw(const Snapshot& snapshot, const CommandSink& post);

  // Geometry of the last draw(), in screen pixels, for the screenshot tests.
  const ScreenRect& banner_rect() const { return banner_; }
  const ScreenRect& plot_rect() const { return plot_; }            // the curve plot's data area
  const ScreenRect& coverage_map_rect() const { return coverage_map_; }
  const ScreenRect& capture_button_rect() const { return capture_button_; }  // empty unless a power is asked for
  const ScreenRect& response_curve_rect() const { return response_curve_; }  // empty unless a response is shown
  const ScreenRect& hold_button_rect() const { return hold_button_; }
  const ScreenRect& camera_hold_rect() const { return camera_hold_rect_; }  // empty unless a lock is shown

  // Where Hold writes the sweep's response: a new folder response-YYYYmmdd-HHMMSS under `root`
  // (the application passes the sessions folder).
  void set_response_root(const std::filesystem::path& root) { response_root_ = root; }
  // What the sweep's camera lock holds (SweepCameraLock::holding), shown while the wizard sweeps.
  void set_camera_hold(std::optional<std::string> hold) { camera_hold_ = std::move(hold); }
  // The exposure the last sweep held a camera at (SweepCameraLock::last_sweep_exposure_ms); with it
  // a response whose sweep stopped short of the top offers "Sweep at N ms", which starts the same
  // sweep again and leaves the factor for take_sweep_again_factor().
  void set_sweep_again_exposure(std::optional<double> exposure_ms) { sweep_again_exposure_ms_ = exposure_ms; }
  std::optional<double> take_sweep_again_factor() { return std::exchange(sweep_again_factor_, std::nullopt); }
  const ScreenRect& sweep_again_button_rect() const { return sweep_again_button_; }  // empty unless offered
  // Where the recommended point was drawn (sweep: on the curve; prior: on the power axis).
  const std::optional<ImVec2>& recommended_marker() const { return marker_; }

private:
  void draw_banner(const Snapshot& snapshot);
  void draw_live_metrics(const Snapshot& snapshot);
  void draw_coverage_map(const FeatureGrid& grid, ImVec2 origin, ImVec2 size);
  void draw_wizard(const IlluminationStatus& status, const Snapshot& snapshot, const CommandSink& post);
  void draw_settings_popup(const IlluminationStatus& status, const CommandSink& post);
  void draw_plot(const IlluminationStatus& status, float height);  // title row and plot in `height`
  void draw_recommendation(const IlluminationStatus& status);
  void draw_sweep_response(const SweepResponse& response, const SweepPlan& plan, const CommandSink& post);

  ScreenRect banner_;
  ScreenRect plot_;
  ScreenRect coverage_map_;
  ScreenRect capture_button_;
  ScreenRect response_curve_;
  ScreenRect hold_button_;
  ScreenRect camera_hold_rect_;
  ScreenRect sweep_again_button_;
  std::optional<double> sweep_again_exposure_ms_;
  std::optional<double> sweep_again_factor_;
  std::filesystem::path response_root_;
  std::optional<std::string> camera_hold_;
  std::optional<ImVec2> marker_;

  // What the operator is typing: the power to confirm follows the wizard's request until edited.
  double power_entry_w_ = 0.0;
  std::optional<std::size_t> power_entry_step_;  // the wizard step the entry was filled for
  int frames_per_power_ = 0;  // 0: the configured plan's
  float share_entry_ = 0.0f;
  float clip_entry_ = 0.0f;
  // Reused between frames so the plot does not allocate every frame.
  std::vector<double> curve_x_;
  std::vector<double> curve_y_;
};

}  // namespace nirslam::ui
