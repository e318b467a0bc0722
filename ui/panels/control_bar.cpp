#include "ui/panels/control_bar.hpp"

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <imgui.h>

#include "nirslam/session/session_format.hpp"
#include "ui/theme.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {
namespace {

void vertical_separator() {
  ImGui::SameLine(0.0f, 12.0f);
  const ImVec2 p = ImGui::GetCursorScreenPos();
  const float h = ImGui::GetFrameHeight();
  ImGui::GetWindowDrawList()->AddLine(ImVec2(p.x, p.y + 3.0f), ImVec2(p.x, p.y + h - 3.0f), colours::border);
  ImGui::Dummy(ImVec2(1.0f, h));
  ImGui::SameLine(0.0f, 12.0f);
}

}  // namespace

const char* state_label(WorkerState state) {
  switch (state) {
    case WorkerState::Idle: return "Idle";
    case WorkerState::Running: return "Running";
    case WorkerState::Paused: return "Paused";
    case WorkerState::Finished: return "Finished";
    case WorkerState::Failed: return "Failed";
  }
  return "Unknown";
}

unsigned state_colour(WorkerState state) {
  switch (state) {
    case WorkerState::Idle: return colours::state_idle;
    case WorkerState::Running: return colours::state_running;
    case WorkerState::Paused: return colours::state_paused;
    case WorkerState::Finished: return colours::state_finished;
    case WorkerState::Failed: return colours::state_failed;
  }
  return colours::state_idle;
}

void ControlBar::draw(const Snapshot& snapshot, const CommandSink& post) {
  const bool can_post = static_cast<bool>(post);
  const WorkerState state = snapshot.state;
  const bool running = state == WorkerState::Running;
  const bool has_source = !snapshot.source.kind.empty() || !snapshot.source.description.empty();

  if (icon_button("start", Icon::Play, "Start",
                  can_post && has_source && !running, "Start or resume processing (Space)"))
    post(command::Start{});
  ImGui::SameLine();
  if (icon_button("pause", Icon::Pause, "Pause", can_post && running, "Pause after the current frame (Space)"))
    post(command::Pause{});
  ImGui::SameLine();
  if (icon_button("step", Icon::Step, "Step", can_post && has_source && !running, "Process exactly one frame (S)"))
    post(command::Step{});
  ImGui::SameLine();
  if (icon_button("stop", Icon::Stop, "Stop", can_post && (running || state == WorkerState::Paused),
                  "Stop and rewind the source to its first frame"))
    post(command::Stop{});

  vertical_separator();
  badge(state_label(state), state_colour(state));
  // Recording is never invisible: a red REC badge with the frames written, whatever tab is open.
  const RecordingStatus& recording = snapshot.recording;
  if (recording.state == RecordingStatus::State::Recording || recording.state == RecordingStatus::State::Failed) {
    ImGui::SameLine();
    const bool failed = recording.state == RecordingStatus::State::Failed;
    const std::string rec = failed ? std::string("REC stopped") : fmt::format("REC {}", recording.frames_written);
    badge(rec.c_str(), failed ? colours::state_failed : colours::saturated);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("%s\n%s free%s", recording.folder.c_str(), human_bytes(recording.free_bytes).c_str(),
                        recording.last_error.empty() ? "" : ("\n" + recording.last_error).c_str());
  }

  // The pipeline mode: which stages run. Switching restarts calibration and odometry.
  vertical_separator();
  ImGui::AlignTextToFramePadding();
  ImGui::TextColored(to_vec4(colours::text_dim), "Mode");
  ImGui::SameLine();
  const auto label = [](PipelineMode mode) -> const char* {
    switch (mode) {
      case PipelineMode::Quality: return "quality only";
      case PipelineMode::Odometry: return "odometry";
      case PipelineMode::Calibrated: return "calibrated odometry";
      case PipelineMode::Illuminated: return "calibrated + lamp";
      case PipelineMode::OdometryIlluminated: return "odometry + lamp";
    }
    return "?";
  };
  const std::vector<PipelineMode> modes = pipeline_modes();
  PipelineMode current = PipelineMode::Calibrated;
  for (const PipelineMode mode : modes)
    if (snapshot.pipeline_mode == to_string(mode)) current = mode;
  const bool automatic = snapshot.pipeline_mode_automatic;
  // The automatic choice shows what it chose, so the operator sees which model runs.
  const std::string preview = automatic ? fmt::format("{} (auto)", label(current)) : std::string(label(current));
  ImGui::SetNextItemWidth(ImGui::CalcTextSize("calibrated odometry (auto)").x + ImGui::GetFrameHeight() + 12.0f);
  if (!can_post) ImGui::BeginDisabled();
  const bool mode_open = ImGui::BeginCombo("##mode", preview.c_str());
  mode_rect_ = last_item_rect();
  if (mode_open) {
    if (ImGui::Selectable("automatic", automatic) && !automatic) {
      chosen_pipeline_mode = "auto";
      post(command::SetPipelineMode{std::nullopt});
    }
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("calibrated + lamp when the source reports its lamp's power, else calibrated odometry");
    ImGui::Separator();
    for (const PipelineMode mode : modes)
      if (ImGui::Selectable(label(mode), !automatic && mode == current) && (automatic || mode != current)) {
        chosen_pipeline_mode = std::string(to_string(mode));
        post(command::SetPipelineMode{mode});
      }
    ImGui::EndCombo();
  }
  if (!can_post) ImGui::EndDisabled();
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip("Which stages run on every frame:\n"
                      "quality only: entropy, clipping, features\n"
                      "odometry: + direct sparse odometry on the raw frames (plain DSO)\n"
                      "calibrated odometry: + online photometric calibration; the odometry sees G(I)/V\n"
                      "calibrated + lamp: + the co-located lamp's distance and power factor in the odometry\n"
                      "odometry + lamp: plain odometry with the lamp's factor, without calibration\n"
                      "automatic: calibrated + lamp when the source reports its lamp's power, else calibrated odometry\n"
                      "Switching restarts the calibration and the odometry.");

  vertical_separator();
  ImGui::AlignTextToFramePadding();
  ImGui::TextColored(to_vec4(colours::text_dim), "Source");
  ImGui::SameLine();
  const std::string source =
      has_source ? (snapshot.source.kind.empty() ? snapshot.source.description
                                                 : fmt::format("{} · {}", snapshot.source.kind, snapshot.source.description))
                 : std::string("none");

  // Right side: where the current frame is in a dataset (it restarts when the source loops), or
  // how many frames a live stream delivered.
  const std::size_t total = snapshot.source.frame_count.value_or(0);
  const std::int64_t position = snapshot.frame ? snapshot.frame->index + 1 : 0;
  const bool seekable = can_post && total > 0 && snapshot.source.seekable;
  // While recording a jump would leave a gap in the session: the bar only shows the progress.
  const bool can_jump = seekable && recording.state != RecordingStatus::State::Recording;
  if (!can_jump) seek_target_.reset();
  const std::string progress = seek_target_ ? fmt::format("-> {} / {}", *seek_target_ + 1, total)
                               : total > 0  ? fmt::format("{} / {}", position, total)
                                            : fmt::format("{} frames", snapshot.frames_processed);
  const float progress_text_width = ImGui::CalcTextSize("000000 / 000000").x;
  const float bar_width = total > 0 ? 160.0f : 0.0f;
  const float right_width = progress_text_width + (bar_width > 0.0f ? bar_width + 10.0f : 0.0f);
  const float right_x = ImGui::GetWindowContentRegionMax().x - right_width;

  // The description is clipped so it never runs into the progress readout.
  const float source_width = std::max(40.0f, right_x - ImGui::GetCursorPosX() - 16.0f);
  const ImVec2 p = ImGui::GetCursorScreenPos();
  const float text_y = p.y + ImGui::GetStyle().FramePadding.y;
  ImGui::Dummy(ImVec2(source_width, ImGui::GetFrameHeight()));
  if (ImGui::IsItemHovered() && has_source) ImGui::SetTooltip("%s", source.c_str());
  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->PushClipRect(p, ImVec2(p.x + source_width, p.y + ImGui::GetFrameHeight()), true);
  draw->AddText(ImVec2(p.x, text_y), colours::text, source.c_str());
  draw->PopClipRect();

  ImGui::SameLine(right_x);
  ImGui::AlignTextToFramePadding();
  right_aligned_text(progress_text_width, progress.c_str(), colours::text_dim);
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip("Position of the current frame in the sequence; %lld frames processed in this run",
                      static_cast<long long>(snapshot.frames_processed));
  progress_rect_ = {};
  if (bar_width > 0.0f) {
    ImGui::SameLine(0.0f, 10.0f);
    const ImVec2 bar = ImGui::GetCursorScreenPos();
    const ImVec2 size(bar_width, ImGui::GetFrameHeight());
    progress_rect_ = {bar, ImVec2(bar.x + size.x, bar.y + size.y)};
    // Frame i (0-based) sits at fraction (i + 1) / total, as the readout counts from 1.
    const auto frame_under = [&](float x) {
      const double f = std::clamp(static_cast<double>(x - bar.x) / bar_width, 0.0, 1.0);
      return std::min(total - 1, static_cast<std::size_t>(std::max(0.0, std::ceil(f * static_cast<double>(total)) - 1.0)));
    };
    if (can_jump) {
      ImGui::InvisibleButton("##seek", size);
      if (ImGui::IsItemActive()) seek_target_ = frame_under(ImGui::GetIO().MousePos.x);
      if (ImGui::IsItemDeactivated() && seek_target_) {
        post(command::Seek{*seek_target_});
        seek_target_.reset();
      }
      if (ImGui::IsItemHovered() && !ImGui::IsItemActive())
        ImGui::SetTooltip("Frame %zu: click or drag to jump there.\nThe calibration and the odometry start again at that frame.",
                          frame_under(ImGui::GetIO().MousePos.x) + 1);
    } else {
      ImGui::Dummy(size);
      if (seekable && ImGui::IsItemHovered()) ImGui::SetTooltip("Stop the recording to jump to another frame");
    }
    const double shown = seek_target_ ? static_cast<double>(*seek_target_ + 1) : static_cast<double>(position);
    const float fraction = static_cast<float>(std::clamp(shown / static_cast<double>(total), 0.0, 1.0));
    const float h = std::round(size.y * 0.4f);
    const float y = std::round(bar.y + 0.5f * (size.y - h));
    draw->AddRectFilled(ImVec2(bar.x, y), ImVec2(bar.x + bar_width, y + h), colours::frame_bg, 2.0f);
    draw->AddRectFilled(ImVec2(bar.x, y), ImVec2(bar.x + bar_width * fraction, y + h), colours::accent, 2.0f);
    if (can_jump) {  // a knob says the bar can be dragged
      const float radius = std::round(size.y * 0.28f);
      draw->AddCircleFilled(ImVec2(bar.x + bar_width * fraction, bar.y + 0.5f * size.y), radius, colours::text);
    }
  }
}

}  // namespace nirslam::ui
