#include "ui/application.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

constexpr ImGuiWindowFlags kTileFlags = ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize |
                                        ImGuiWindowFlags_NoCollapse | ImGuiWindowFlags_NoSavedSettings |
                                        ImGuiWindowFlags_NoBringToFrontOnFocus | ImGuiWindowFlags_NoScrollbar |
                                        ImGuiWindowFlags_NoScrollWithMouse;
constexpr ImGuiWindowFlags kBarFlags = kTileFlags | ImGuiWindowFlags_NoTitleBar;
// The tiles cover the display and their background is the colour the frame is cleared to: not
// filling it again saves a full-screen blended pass, most of a frame's cost on a software
// rasteriser (Mesa llvmpipe). The bars have their own, darker background.
constexpr ImGuiWindowFlags kPlainTile = kTileFlags | ImGuiWindowFlags_NoBackground;
constexpr ImGuiWindowFlags kPlainBar = kBarFlags | ImGuiWindowFlags_NoBackground;

// The strip's tabs as the settings file names them.
constexpr std::pair<Application::StripTab, const char*> kTabNames[] = {
    {Application::StripTab::Illumination, "illumination"}, {Application::StripTab::Photometric, "photometric"},
    {Application::StripTab::Session, "session"},           {Application::StripTab::Record, "record"},
    {Application::StripTab::Camera, "camera"}};

bool begin_tile(const char* name, const ScreenRect& rect, ImGuiWindowFlags flags) {
  ImGui::SetNextWindowPos(rect.min);
  ImGui::SetNextWindowSize(rect.size());
  return ImGui::Begin(name, nullptr, flags);
}

}  // namespace

Application::Application(const std::filesystem::path& shader_dir, CommandSink post)
    : post_(std::move(post)), feed_(shader_dir), view3d_(shader_dir) {
  recording_.on_export_done = [this](bool ok, const std::string& line) {
    notifications_.push(ok ? NotificationArea::Severity::Notice : NotificationArea::Severity::Error, line);
  };
}

Application::Layout Application::compute_layout(ImVec2 display) const {
  const ImGuiStyle& style = ImGui::GetStyle();
  Layout layout;
  const float w = std::floor(display.x);
  const float h = std::floor(display.y);
  float top = 0.0f;
  float bottom = h;
  if (panels.controls) {
    const float bar = std::round(ImGui::GetFrameHeight() + 2.0f * style.WindowPadding.y + 2.0f);
    layout.controls = {ImVec2(0.0f, 0.0f), ImVec2(w, bar)};
    top = bar;
  }
  if (panels.status) {
    const float bar = std::round(ImGui::GetTextLineHeight() + 2.0f * 5.0f);
    layout.status = {ImVec2(0.0f, h - bar), ImVec2(w, h)};
    bottom = h - bar;
  }
  // The measurement column: about a third of the width, readable at any window size.
  const float width = std::clamp(std::round(0.34f * w), std::min(380.0f, 0.5f * w), 600.0f);
  const bool left_panels = panels.feed || panels.view3d || panels.illumination || panels.photometric || panels.session || panels.record || panels.camera;
  const float split = !panels.entropy ? w : left_panels ? w - width : 0.0f;
  if (panels.entropy) layout.entropy = {ImVec2(split, top), ImVec2(w, bottom)};
  // Under the feed and the 3-D view, a strip for the illumination and photometric tabs: wide
  // enough for the plots side by side, short enough to leave the views most of the height.
  const bool strip = panels.illumination || panels.photometric || panels.session || panels.record || panels.camera;
  const bool views = panels.feed || panels.view3d;
  float strip_top = bottom;
  if (strip) {
    const float middle = bottom - top;
    strip_top = views ? bottom - std::clamp(std::round(0.36f * middle), std::min(240.0f, std::round(0.45f * middle)), 360.0f)
                      : top;
    layout.strip = {ImVec2(0.0f, strip_top), ImVec2(split, bottom)};
  }
  // The feed keeps the larger share: a 4:3 frame needs more width than the 3-D view.
  const float view_split = !panels.view3d ? split : !panels.feed ? 0.0f : std::round(0.55f * split);
  if (panels.feed) layout.feed = {ImVec2(0.0f, top), ImVec2(view_split, strip_top)};
  if (panels.view3d) layout.view3d = {ImVec2(view_split, top), ImVec2(split, strip_top)};
  return layout;
}

void Application::draw(const Snapshot& snapshot) {
  notifications_.observe(snapshot);
  watch_camera();
  lock_camera_for_sweep(snapshot);
  handle_shortcuts(snapshot);
  layout_ = compute_layout(ImGui::GetIO().DisplaySize);

  if (panels.controls) {
    ImGui::PushStyleColor(ImGuiCol_WindowBg, to_vec4(rgba(24, 26, 30)));
    if (begin_tile("##controls", layout_.controls, kBarFlags)) controls_.draw(snapshot, post_);
    ImGui::End();
    ImGui::PopStyleColor();
  }
  if (panels.feed) {
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(8.0f, 6.0f));
    if (begin_tile("Feed###feed", layout_.feed, kPlainTile)) feed_.draw(snapshot);
    ImGui::End();
    ImGui::PopStyleVar();
  }
  if (panels.entropy) {
    if (begin_tile("Image quality###entropy", layout_.entropy, kPlainTile)) entropy_.draw(snapshot);
    ImGui::End();
  }
  if (panels.view3d) {
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(8.0f, 6.0f));
    if (begin_tile("3-D view###view3d", layout_.view3d, kPlainTile)) view3d_.draw(snapshot);
    ImGui::End();
    ImGui::PopStyleVar();
  }
  if (panels.illumination || panels.photometric || panels.session || panels.record || panels.camera) draw_strip(snapshot);
  if (panels.status) {
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(10.0f, 5.0f));
    ImGui::PushStyleColor(ImGuiCol_WindowBg, to_vec4(rgba(24, 26, 30)));
    if (begin_tile("##status", layout_.status, kBarFlags)) status_.draw(snapshot);
    ImGui::End();
    ImGui::PopStyleColor();
    ImGui::PopStyleVar();
  }
  // Over the views: what the operator must not miss, and the shortcut list.
  ScreenRect views = layout_.feed;
  if (!layout_.view3d.empty()) views = views.empty() ? layout_.view3d : ScreenRect{views.min, layout_.view3d.max};
  if (views.empty()) views = {ImVec2(0.0f, 0.0f), ImGui::GetIO().DisplaySize};
  notifications_.draw(views);
  help_.draw(views);
}

void Application::draw_strip(const Snapshot& snapshot) {
  struct Tab {
    StripTab id;
    const char* label;
    bool shown;
  };
  const Tab tabs[] = {{StripTab::Illumination, "Illumination", panels.illumination},
                      {StripTab::Photometric, "Photometric", panels.photometric},
                      {StripTab::Session, "Session", panels.session},
                      {StripTab::Record, "Record", panels.record},
                      {StripTab::Camera, "Camera", panels.camera}};
  const auto draw_tab = [&](StripTab tab) {
    current_tab_ = tab;
    switch (tab) {
      case StripTab::Illumination:
        illumination_.set_response_root(recording_.sessions_folder());
        illumination_.draw(snapshot, post_);
        if (const auto factor = illumination_.take_sweep_again_factor()) sweep_camera_lock_.sweep_again_at(*factor);
        break;
      case StripTab::Photometric: photometric_.draw(snapshot); break;
      case StripTab::Session: session_.draw(snapshot, post_, session_actions_); break;
      case StripTab::Record: recording_.draw(snapshot, post_, session_actions_); break;
      case StripTab::Camera: draw_camera_tab(); break;
    }
  };
  int shown = 0;
  const Tab* only = nullptr;
  for (const Tab& tab : tabs)
    if (tab.shown) {
      ++shown;
      only = &tab;
    }
  if (shown == 1) {
    const std::string title = std::string(only->label) + "###strip";
    if (begin_tile(title.c_str(), layout_.strip, kPlainTile)) draw_tab(only->id);
    ImGui::End();
    return;
  }
  if (begin_tile("##strip", layout_.strip, kPlainBar) && ImGui::BeginTabBar("##strip_tabs")) {
    for (const Tab& tab : tabs) {
      if (!tab.shown) continue;
      const ImGuiTabItemFlags flags = requested_tab_ == tab.id ? ImGuiTabItemFlags_SetSelected : ImGuiTabItemFlags_None;
      if (ImGui::BeginTabItem(tab.label, nullptr, flags)) {
        draw_tab(tab.id);
        ImGui::EndTabItem();
      }
    }
    requested_tab_.reset();
    ImGui::EndTabBar();
  }
  ImGui::End();
}

// A camera that goes away (or fails) says so in the window whatever tab is open: the stream ends
// cleanly and the worker only sees the end of its source.
void Application::watch_camera() {
  const std::shared_ptr<CameraControls> controls =
      session_actions_.camera_controls ? session_actions_.camera_controls() : nullptr;
  if (!controls) {
    camera_connection_.reset();
    return;
  }
  const CameraState state = controls->state();
  if (camera_connection_ != state.connection) {
    const std::string what = state.device.empty() ? std::string("the camera") : state.device;
    if (state.connection == CameraConnection::Unplugged)
      notifications_.push(NotificationArea::Severity::Warning,
                          fmt::format("{} disappeared: {} frames captured are kept. {}", what, state.frames_captured,
                                      state.message));
    else if (state.connection == CameraConnection::Failed)
      notifications_.push(NotificationArea::Severity::Error,
                          fmt::format("{}: {}", what, state.error.empty() ? state.message : state.error));
    else if (state.connection == CameraConnection::Streaming && camera_connection_ == CameraConnection::Reconnecting)
      notifications_.push(NotificationArea::Severity::Notice, what + " is back and streaming again.");
    camera_connection_ = state.connection;
  }
}

// The wizard's power sweep runs on the worker; the camera's controls are the GUI's. Holding the
// exposure for the sweep here keeps the worker free of camera controls.
void Application::lock_camera_for_sweep(const Snapshot& snapshot) {
  const std::shared_ptr<CameraControls> controls =
      session_actions_.camera_controls ? session_actions_.camera_controls() : nullptr;
  const SweepStage stage = snapshot.illumination ? snapshot.illumination->progress.stage : SweepStage::Idle;
  const SweepCameraLock::Change change = sweep_camera_lock_.update(stage, controls);
  using Event = SweepCameraLock::Event;
  if (change.event == Event::OperatorUnlocked || change.event == Event::Failed)
    notifications_.push(NotificationArea::Severity::Warning, change.message);
  else if (change.event != Event::None)
    notifications_.push(NotificationArea::Severity::Notice, change.message);
  illumination_.set_camera_hold(sweep_camera_lock_.holding());
  illumination_.set_sweep_again_exposure(controls ? sweep_camera_lock_.last_sweep_exposure_ms() : std::nullopt);
}

void Application::draw_camera_tab() {
  const std::shared_ptr<CameraControls> controls =
      session_actions_.camera_controls ? session_actions_.camera_controls() : nullptr;
  if (!controls) {
    ImGui::Spacing();
    ImGui::TextColored(to_vec4(colours::text_dim),
                       "No camera is streaming. Open one in the Session tab (O): Camera, or the emulated cameras.");
    return;
  }
  camera_.draw(controls->state(), controls.get());
}

bool Application::select_tab(std::string_view name) {
  for (const auto& [tab, tab_name] : kTabNames)
    if (name == tab_name) {
      select_tab(tab);
      return true;
    }
  return false;
}

void Application::apply(const UiPreferences& p) {
  feed_.show_corrected = p.feed_corrected;
  feed_.highlight_clipping = p.feed_clipping;
  feed_.show_points = p.feed_points;
  view3d_.show_points = p.view3d_points;
  view3d_.show_keyframes = p.view3d_keyframes;
  view3d_.show_ground_truth = p.view3d_ground_truth;
  view3d_.follow = p.view3d_follow;
  view3d_.colouring = p.view3d_colour_by_error ? TrajectoryPanel::Colouring::Error : TrajectoryPanel::Colouring::Time;
  session_.recent_sources = p.recent_sources;
  if (!p.last_source.empty()) session_.select(p.last_source);
  session_.set_recorded_speed(p.recorded_speed);
  recording_.set_sessions_folder(p.sessions_folder);
  select_tab(StripTab::Illumination);
  select_tab(p.strip_tab);
  if (post_) {
    // Only a mode the operator picked overrides the config's.
    controls_.chosen_pipeline_mode = p.chosen_pipeline_mode;
    if (p.chosen_pipeline_mode == "auto") post_(command::SetPipelineMode{std::nullopt});
    else if (const auto mode = parse_pipeline_mode(p.chosen_pipeline_mode)) post_(command::SetPipelineMode{*mode});
    post_(command::SetPacing{p.recorded_speed ? Pacing::RecordedSpeed : Pacing::AsFastAsPossible});
  }
}

void Application::capture(UiPreferences& p) const {
  p.feed_corrected = feed_.show_corrected;
  p.feed_clipping = feed_.highlight_clipping;
  p.feed_points = feed_.show_points;
  p.view3d_points = view3d_.show_points;
  p.view3d_keyframes = view3d_.show_keyframes;
  p.view3d_ground_truth = view3d_.show_ground_truth;
  p.view3d_follow = view3d_.follow;
  p.view3d_colour_by_error = view3d_.colouring == TrajectoryPanel::Colouring::Error;
  p.recent_sources = session_.recent_sources;
  p.recorded_speed = session_.recorded_speed();
  p.sessions_folder = recording_.sessions_folder();
  p.chosen_pipeline_mode = controls_.chosen_pipeline_mode;
  for (const auto& [tab, name] : kTabNames)
    if (tab == current_tab_) p.strip_tab = name;
}

void Application::handle_shortcuts(const Snapshot& snapshot) {
  const ImGuiIO& io = ImGui::GetIO();
  if (io.WantTextInput || io.KeyCtrl || io.KeyAlt || io.KeySuper) return;
  // Letters have no ImGuiKey in 1.86; the typed character is layout-aware and backend-neutral.
  for (const ImWchar c : io.InputQueueCharacters)
    if (const Shortcut* shortcut = shortcut_for(c)) run_shortcut(shortcut->id, snapshot);
}

void Application::run_shortcut(ShortcutAction action, const Snapshot& snapshot) {
  const bool has_source = !snapshot.source.kind.empty() || !snapshot.source.description.empty();
  const bool can_control = static_cast<bool>(post_) && has_source;
  switch (action) {
    case ShortcutAction::StartPause:
      if (!can_control) break;
      if (snapshot.state == WorkerState::Running)
        post_(command::Pause{});
      else
        post_(command::Start{});
      break;
    case ShortcutAction::Step:
      if (can_control && snapshot.state != WorkerState::Running) post_(command::Step{});
      break;
    case ShortcutAction::Stop:
      if (can_control && (snapshot.state == WorkerState::Running || snapshot.state == WorkerState::Paused))
        post_(command::Stop{});
      break;
    case ShortcutAction::ToggleCorrected: feed_.show_corrected = !feed_.show_corrected; break;
    case ShortcutAction::FitViews:
      feed_.fit();
      view3d_.fit_all();
      break;
    case ShortcutAction::FollowCamera: view3d_.follow = !view3d_.follow; break;
    case ShortcutAction::TopView: view3d_.top_view(); break;
    case ShortcutAction::SessionTab: select_tab(StripTab::Session); break;
    case ShortcutAction::IlluminationTab: select_tab(StripTab::Illumination); break;
    case ShortcutAction::PhotometricTab: select_tab(StripTab::Photometric); break;
    case ShortcutAction::Help: help_.visible = !help_.visible; break;
    case ShortcutAction::ToggleRecording: recording_.toggle_recording(snapshot, post_); break;
    case ShortcutAction::RecordTab: select_tab(StripTab::Record); break;
    case ShortcutAction::CameraTab: select_tab(StripTab::Camera); break;
  }
}

}  // namespace nirslam::ui
