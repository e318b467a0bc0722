#include "ui/panels/session_panel.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <fmt/format.h>
#include <imgui.h>

#include "nirslam/config/ui_preferences.hpp"
#include "ui/panels/control_bar.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

constexpr const char* kScenes[] = {"tunnel", "room", "parking", "outdoor"};
constexpr const char* kSceneLabels[] = {"pipe tunnel", "indoor room", "underground parking", "outdoor street"};
constexpr int kSceneCount = 4;
constexpr float kMinPowerW = 5.0f;
constexpr float kMaxPowerW = 200.0f;

}  // namespace

void SessionPanel::select(const std::string& source) {
  error_.clear();
  if (source.rfind("sim", 0) == 0) {
    kind_ = SourceKind::Simulator;
    const std::string spec = source.size() > 4 ? source.substr(4) : "tunnel";
    const std::string scene = spec.substr(0, spec.find('@'));
    for (int i = 0; i < kSceneCount; ++i)
      if (scene == kScenes[i]) scene_ = i;
    if (const auto at = spec.find('@'); at != std::string::npos) {
      try {
        power_w_ = std::clamp(std::stof(spec.substr(at + 1)), kMinPowerW, kMaxPowerW);
      } catch (const std::exception&) {
      }
    }
    return;
  }
  if (source.rfind("v4l2:", 0) == 0 || source.rfind("v4l2-emulated:", 0) == 0) {
    kind_ = SourceKind::Camera;
    emulated_cameras_ = source.rfind("v4l2-emulated:", 0) == 0;
    return;
  }
  if (source.rfind("session:", 0) == 0) {
    kind_ = SourceKind::Recording;
    copy_into(session_path_, source.substr(8));
    return;
  }
  kind_ = SourceKind::Dataset;
  copy_into(dataset_path_, source);
}

std::string SessionPanel::chosen_source() const {
  switch (kind_) {
    case SourceKind::Simulator:
      return fmt::format("sim:{}@{}W", kScenes[scene_], static_cast<int>(std::lround(power_w_)));
    case SourceKind::Dataset: return std::string(dataset_path_.data());
    case SourceKind::Recording:
      return session_path_[0] == '\0' ? std::string() : "session:" + std::string(session_path_.data());
    case SourceKind::Camera: return device_list_.selected_source(devices_, emulated_cameras_).value_or("");
  }
  return {};
}

void SessionPanel::open(const std::string& source, const SessionActions& actions) {
  if (source.empty()) {
    error_ = kind_ == SourceKind::Dataset   ? "Enter the dataset folder first."
             : kind_ == SourceKind::Camera ? "Choose a camera first."
                                           : "Enter the session folder first.";
    return;
  }
  if (!actions.open_source) {
    error_ = "Opening sources is not available here.";
    return;
  }
  error_ = actions.open_source(source);
  if (error_.empty()) {
    last_opened_ = source;
    if (on_source_opened) on_source_opened(source);
    std::vector<std::string> recent{source};
    for (std::string& older : recent_sources)
      if (older != source && recent.size() < UiPreferences::kMaxRecentSources) recent.push_back(std::move(older));
    recent_sources = std::move(recent);
  }
}

void SessionPanel::draw(const Snapshot& snapshot, const CommandSink& post, const SessionActions& actions) {
  const float full = ImGui::GetContentRegionAvail().x;
  const float gap = ImGui::GetStyle().ItemSpacing.x * 2.0f;
  const float picker_width = std::round(0.42f * (full - 2.0f * gap));
  const float recent_width = std::round(0.28f * (full - 2.0f * gap));
  const float height = ImGui::GetContentRegionAvail().y;

  ImGui::BeginChild("##picker", ImVec2(picker_width, height), false);
  draw_picker(actions);
  ImGui::EndChild();
  ImGui::SameLine(0.0f, gap);
  ImGui::BeginChild("##recent", ImVec2(recent_width, height), false);
  draw_recent(actions);
  ImGui::EndChild();
  ImGui::SameLine(0.0f, gap);
  ImGui::BeginChild("##playback", ImVec2(0.0f, height), false);
  draw_playback(snapshot, post);
  ImGui::EndChild();
}

void SessionPanel::draw_picker(const SessionActions& actions) {
  error_rect_ = {};
  section_title("Source");
  const auto kind_button = [this](const char* label, SourceKind kind) {
    if (ImGui::RadioButton(label, kind_ == kind)) {
      kind_ = kind;
      error_.clear();
    }
  };
  kind_button("Simulator", SourceKind::Simulator);
  ImGui::SameLine();
  kind_button("Dataset", SourceKind::Dataset);
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("A dataset folder: TUM monoVO, EuRoC (mav0/cam0) or a folder of images");
  ImGui::SameLine();
  kind_button("Session", SourceKind::Recording);
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("A session recorded with nirslam (replayed with its exposures and powers)");
  ImGui::SameLine();
  kind_button("Camera", SourceKind::Camera);
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("A live V4L2 camera (UVC NIR cameras, mono or side-by-side stereo)");
  if (kind_ == SourceKind::Camera) {
    draw_cameras(actions);
    return;
  }

  bool submit = false;
  const float label_width = ImGui::CalcTextSize("Lamp power").x + 12.0f;
  const auto label = [label_width](const char* text) {
    ImGui::AlignTextToFramePadding();
    ImGui::TextUnformatted(text);
    ImGui::SameLine(label_width);
    ImGui::SetNextItemWidth(-1.0f);
  };
  switch (kind_) {
    case SourceKind::Simulator:
      label("Scene");
      if (ImGui::BeginCombo("##scene", kSceneLabels[scene_])) {
        for (int i = 0; i < kSceneCount; ++i)
          if (ImGui::Selectable(kSceneLabels[i], i == scene_)) scene_ = i;
        ImGui::EndCombo();
      }
      label("Lamp power");
      ImGui::SliderFloat("##power", &power_w_, kMinPowerW, kMaxPowerW, "%.0f W", ImGuiSliderFlags_AlwaysClamp);
      if (ImGui::IsItemHovered())
        ImGui::SetTooltip("The simulated illuminator's power at the start; the Illumination tab changes it live.");
      break;
    case SourceKind::Dataset:
      label("Folder");
      submit = ImGui::InputTextWithHint("##dataset", "/path/to/dataset (TUM monoVO, EuRoC mav0, images)",
                                        dataset_path_.data(), dataset_path_.size(),
                                        ImGuiInputTextFlags_EnterReturnsTrue);
      break;
    case SourceKind::Recording:
      label("Session");
      submit = ImGui::InputTextWithHint("##session", "/path/to/session folder", session_path_.data(),
                                        session_path_.size(), ImGuiInputTextFlags_EnterReturnsTrue);
      break;
    case SourceKind::Camera: break;  // drawn by draw_cameras()
  }
  ImGui::Spacing();
  const bool enabled = static_cast<bool>(actions.open_source);
  if (!enabled) ImGui::BeginDisabled();
  if (ImGui::Button("Open source", ImVec2(ImGui::CalcTextSize("Open source").x + 28.0f, 0.0f))) submit = true;
  open_button_ = last_item_rect();
  if (!enabled) ImGui::EndDisabled();
  if (submit && enabled) open(chosen_source(), actions);
  ImGui::SameLine();
  ImGui::AlignTextToFramePadding();
  const std::string chosen = chosen_source();
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", chosen.empty() ? "" : chosen.c_str());

  error_rect_ = {};
  if (!error_.empty()) {
    ImGui::PushStyleColor(ImGuiCol_Text, to_vec4(colours::state_failed));
    ImGui::TextWrapped("%s", error_.c_str());
    ImGui::PopStyleColor();
    error_rect_ = last_item_rect();
  }
}

void SessionPanel::draw_cameras(const SessionActions& actions) {
  if (!actions.list_cameras) {
    ImGui::TextColored(to_vec4(colours::text_dim), "Cameras are not available here.");
    return;
  }
  bool refresh = !devices_listed_;
  if (ImGui::Checkbox("Emulated cameras", &emulated_cameras_)) refresh = true;
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("The emulated UVC driver's cameras, for trying the camera path without one");
  ImGui::SameLine();
  if (ImGui::SmallButton("Refresh")) refresh = true;
  if (refresh) {
    devices_ = actions.list_cameras(emulated_cameras_);
    devices_listed_ = true;
  }
  ImGui::BeginChild("##devices", ImVec2(0.0f, 0.0f), false);
  if (const std::optional<std::string> source = device_list_.draw(devices_, emulated_cameras_)) open(*source, actions);
  open_button_ = device_list_.open_button_rect();
  if (!error_.empty()) {
    ImGui::PushStyleColor(ImGuiCol_Text, to_vec4(colours::state_failed));
    ImGui::TextWrapped("%s", error_.c_str());
    ImGui::PopStyleColor();
    error_rect_ = last_item_rect();
  }
  ImGui::EndChild();
}

void SessionPanel::draw_recent(const SessionActions& actions) {
  section_title("Recent sources");
  const ImVec2 top = ImGui::GetCursorScreenPos();
  if (recent_sources.empty()) {
    ImGui::TextColored(to_vec4(colours::text_dim), "Sources you open are listed here.");
  }
  std::string reopen;
  for (std::size_t i = 0; i < recent_sources.size(); ++i) {
    const std::string& source = recent_sources[i];
    ImGui::PushID(static_cast<int>(i));
    const bool current = source == last_opened_;
    if (ImGui::Selectable(source.c_str(), current) && actions.open_source) reopen = source;
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("Open %s again", source.c_str());
    ImGui::PopID();
  }
  recent_rect_ = {top, ImVec2(top.x + ImGui::GetContentRegionAvail().x, ImGui::GetCursorScreenPos().y)};
  if (!reopen.empty()) {
    select(reopen);
    open(reopen, actions);
  }
}

void SessionPanel::draw_playback(const Snapshot& snapshot, const CommandSink& post) {
  section_title("Playback");
  const bool can_post = static_cast<bool>(post);
  if (!can_post) ImGui::BeginDisabled();
  if (ImGui::RadioButton("Recorded speed", recorded_speed_)) {
    recorded_speed_ = true;
    post(command::SetPacing{Pacing::RecordedSpeed});
  }
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip("Play datasets and sessions at the pace they were captured");
  ImGui::SameLine();
  if (ImGui::RadioButton("Fastest", !recorded_speed_)) {
    recorded_speed_ = false;
    post(command::SetPacing{Pacing::AsFastAsPossible});
  }
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip("Process every frame as fast as the pipeline can (batch work)");
  if (!can_post) ImGui::EndDisabled();

  ImGui::Spacing();
  badge(state_label(snapshot.state), state_colour(snapshot.state));
  ImGui::SameLine();
  ImGui::AlignTextToFramePadding();
  const std::size_t total = snapshot.source.frame_count.value_or(0);
  const std::int64_t position = snapshot.frame ? snapshot.frame->index + 1 : 0;
  if (total > 0)
    ImGui::Text("frame %lld of %zu", static_cast<long long>(position), total);
  else
    ImGui::Text("%lld frames", static_cast<long long>(snapshot.frames_processed));
  if (!snapshot.source.description.empty()) {
    ImGui::TextColored(to_vec4(colours::text_dim), "%s", snapshot.source.kind.c_str());
    ImGui::SameLine();
    ImGui::TextWrapped("%s", snapshot.source.description.c_str());
  }
  if (snapshot.source.live && snapshot.frames_dropped > 0)
    ImGui::TextColored(to_vec4(colours::banner_dark), "%lld frames dropped (the pipeline lagged)",
                       static_cast<long long>(snapshot.frames_dropped));
  ImGui::PushStyleColor(ImGuiCol_Text, to_vec4(colours::text_dim));
  ImGui::TextWrapped("Space start/pause · S step · X stop · H all shortcuts");
  ImGui::PopStyleColor();
}

}  // namespace nirslam::ui
