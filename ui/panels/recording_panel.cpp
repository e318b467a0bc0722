#include "ui/panels/recording_panel.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <system_error>

#include <fmt/format.h>
#include <imgui.h>

#include "nirslam/session/session_export.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
constexpr auto kScanPeriod = std::chrono::seconds(3);

ImU32 state_colour(RecordingStatus::State state) {
  switch (state) {
    case RecordingStatus::State::Off: return colours::state_idle;
    case RecordingStatus::State::Recording: return colours::saturated;
    case RecordingStatus::State::Stopped: return colours::state_finished;
    case RecordingStatus::State::Failed: return colours::state_failed;
  }
  return colours::state_idle;
}

void row(const char* label, const std::string& value, ImU32 colour = 0) {
  ImGui::TableNextRow();
  ImGui::TableNextColumn();
  ImGui::TextColored(to_vec4(colours::text_dim), "%s", label);
  ImGui::TableNextColumn();
  if (colour != 0)
    ImGui::TextColored(to_vec4(colour), "%s", value.c_str());
  else
    ImGui::TextUnformatted(value.c_str());
}

}  // namespace

fs::path default_sessions_folder() {
  const char* home = std::getenv("HOME");
  return fs::path(home != nullptr && *home != '\0' ? home : ".") / "nirslam-sessions";
}

RecordingPanel::RecordingPanel() { copy_into(folder_, default_sessions_folder().string()); }

RecordingPanel::~RecordingPanel() { wait_for_export(); }

void RecordingPanel::wait_for_export() {
  if (!export_job_.valid()) return;
  export_job_.wait();
  collect_export();
}

void RecordingPanel::set_sessions_folder(const std::string& folder) {
  if (!folder.empty()) copy_into(folder_, folder);
  rescan();
}

fs::path RecordingPanel::next_session_folder() const {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char name[64];
  std::strftime(name, sizeof(name), "session-%Y%m%d-%H%M%S", &utc);
  fs::path folder = fs::path(folder_.data()) / name;
  // Two recordings in the same second get distinct folders.
  std::error_code error;
  for (int i = 2; fs::exists(folder, error); ++i) folder = fs::path(folder_.data()) / fmt::format("{}-{}", name, i);
  return folder;
}

void RecordingPanel::toggle_recording(const Snapshot& snapshot, const CommandSink& post) {
  if (!post) return;
  if (snapshot.recording.state == RecordingStatus::State::Recording) {
    post(command::StopRecording{});
    return;
  }
  std::error_code error;
  fs::create_directories(fs::path(folder_.data()), error);  // the recorder reports what fails
  post(command::StartRecording{next_session_folder(), std::string(notes_.data())});
  if (snapshot.state != WorkerState::Running) post(command::Start{});
}

void RecordingPanel::draw(const Snapshot& snapshot, const CommandSink& post, const SessionActions& actions) {
  collect_export();
  if (snapshot.recording.state != last_state_) {
    // A recording that ended is a new session in the list.
    if (last_state_ == RecordingStatus::State::Recording) rescan();
    last_state_ = snapshot.recording.state;
  }
  scan_if_due();

  const float full = ImGui::GetContentRegionAvail().x;
  const float gap = ImGui::GetStyle().ItemSpacing.x * 2.0f;
  const float left = std::round(0.45f * (full - gap));
  const float height = ImGui::GetContentRegionAvail().y;
  ImGui::BeginChild("##record", ImVec2(left, height), false);
  draw_controls(snapshot, post);
  draw_status(snapshot.recording);
  ImGui::EndChild();
  ImGui::SameLine(0.0f, gap);
  ImGui::BeginChild("##sessions", ImVec2(0.0f, height), false);
  draw_sessions(actions);
  ImGui::EndChild();
}

void RecordingPanel::draw_controls(const Snapshot& snapshot, const CommandSink& post) {
  section_title("Record");
  const float label_width = ImGui::CalcTextSize("Sessions in").x + 12.0f;
  const auto label = [label_width](const char* text) {
    ImGui::AlignTextToFramePadding();
    ImGui::TextUnformatted(text);
    ImGui::SameLine(label_width);
    ImGui::SetNextItemWidth(-1.0f);
  };
  const bool recording = snapshot.recording.state == RecordingStatus::State::Recording;
  if (recording) ImGui::BeginDisabled();
  label("Sessions in");
  if (ImGui::InputText("##sessions_folder", folder_.data(), folder_.size())) rescan();
  label("Notes");
  ImGui::InputTextWithHint("##notes", "operator, site, lamp, anything worth knowing later", notes_.data(), notes_.size());
  if (recording) ImGui::EndDisabled();

  const bool can_post = static_cast<bool>(post);
  const bool has_source = !snapshot.source.kind.empty() || !snapshot.source.description.empty();
  const bool enabled = can_post && (recording || has_source);
  if (!enabled) ImGui::BeginDisabled();
  ImGui::PushStyleColor(ImGuiCol_Button, to_vec4(recording ? colours::frame_bg : rgba(150, 40, 36)));
  ImGui::PushStyleColor(ImGuiCol_ButtonHovered, to_vec4(recording ? colours::border : rgba(190, 52, 46)));
  const char* text = recording ? "Stop recording" : "Record";
  if (ImGui::Button(text, ImVec2(ImGui::CalcTextSize("Stop recording").x + 28.0f, 0.0f))) toggle_recording(snapshot, post);
  ImGui::PopStyleColor(2);
  record_button_ = last_item_rect();
  if (!enabled) ImGui::EndDisabled();
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip(recording ? "Stop and finish the session (R): the trajectory and calibration are written into it"
                                : "Record every frame losslessly into a new session folder (R)");
  ImGui::SameLine();
  ImGui::AlignTextToFramePadding();
  if (free_bytes_)
    ImGui::TextColored(to_vec4(colours::text_dim), "%s free", human_bytes(*free_bytes_).c_str());
  else if (!free_error_.empty())
    ImGui::TextColored(to_vec4(colours::banner_dark), "%s", free_error_.c_str());
}

void RecordingPanel::draw_status(const RecordingStatus& status) {
  ImGui::Spacing();
  const ImVec2 top = ImGui::GetCursorScreenPos();
  badge(to_string(status.state), state_colour(status.state));
  if (status.state == RecordingStatus::State::Off) {
    ImGui::SameLine();
    ImGui::AlignTextToFramePadding();
    ImGui::TextColored(to_vec4(colours::text_dim), "frames are written losslessly, with a journal, as they arrive");
  }
  if (status.state != RecordingStatus::State::Off &&
      ImGui::BeginTable("##recording_status", 2, ImGuiTableFlags_SizingFixedFit)) {
    row("Folder", status.folder);
    row("Frames", fmt::format("{} written, {} queued", status.frames_written, status.queued));
    row("Dropped", fmt::format("{}", status.frames_dropped), status.frames_dropped > 0 ? colours::banner_dark : 0u);
    row("Written", human_bytes(status.bytes_written));
    const bool low = status.minutes_left && *status.minutes_left < 10.0;
    row("Free", status.minutes_left ? fmt::format("{} · {:.0f} min left", human_bytes(status.free_bytes), *status.minutes_left)
                                    : human_bytes(status.free_bytes),
        low ? colours::banner_dark : 0u);
    ImGui::EndTable();
  }
  if (!status.message.empty() && status.last_error.empty()) {
    ImGui::PushStyleColor(ImGuiCol_Text, to_vec4(colours::text_dim));
    ImGui::TextWrapped("%s", status.message.c_str());
    ImGui::PopStyleColor();
  }
  if (!status.last_error.empty()) {
    ImGui::PushStyleColor(ImGuiCol_Text, to_vec4(colours::state_failed));
    ImGui::TextWrapped("%s", status.last_error.c_str());
    ImGui::PopStyleColor();
  }
  status_ = {top, ImVec2(top.x + ImGui::GetContentRegionAvail().x, ImGui::GetCursorScreenPos().y)};
}

void RecordingPanel::draw_sessions(const SessionActions& actions) {
  section_title("Recorded sessions");
  const ImVec2 top = ImGui::GetCursorScreenPos();
  const float list_height = std::max(3.0f * ImGui::GetFrameHeight(),
                                     ImGui::GetContentRegionAvail().y - 2.0f * ImGui::GetFrameHeightWithSpacing() - 4.0f);
  ImGui::BeginChild("##session_list", ImVec2(0.0f, list_height), false);
  if (sessions_.empty()) ImGui::TextColored(to_vec4(colours::text_dim), "No sessions in this folder yet.");
  for (int i = 0; i < static_cast<int>(sessions_.size()); ++i) {
    const SessionEntry& entry = sessions_[static_cast<std::size_t>(i)];
    const SessionMetadata& m = entry.metadata;
    const std::string line =
        fmt::format("{}  ·  {} frames  ·  {}{}", entry.folder.filename().string(), m.frames_written, to_string(m.state),
                    m.notes.empty() ? "" : "  ·  " + m.notes);
    ImGui::PushID(i);
    if (ImGui::Selectable(line.c_str(), selected_ == i)) {
      selected_ = i;
      copy_into(export_folder_, entry.folder.string() + "-export");
    }
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("%s\nstarted %s · %s, %d x %d, %d-bit\n%s", entry.folder.string().c_str(), m.started_utc.c_str(),
                        m.source_description.c_str(), m.width, m.height, m.bit_depth, m.stop_reason.c_str());
    ImGui::PopID();
  }
  ImGui::EndChild();
  sessions_rect_ = {top, ImVec2(top.x + ImGui::GetContentRegionAvail().x, top.y + list_height)};

  const bool chosen = selected_ >= 0 && selected_ < static_cast<int>(sessions_.size());
  if (!chosen) ImGui::BeginDisabled();
  if (ImGui::Button("Replay") && chosen && actions.open_source) {
    const std::string refused = actions.open_source("session:" + sessions_[static_cast<std::size_t>(selected_)].folder.string());
    if (!refused.empty()) {
      export_result_ = refused;
      export_failed_ = true;
    }
  }
  ImGui::SameLine();
  const bool busy = export_job_.valid();
  if (busy) ImGui::BeginDisabled();
  if (ImGui::Button("Export to") && chosen) start_export(sessions_[static_cast<std::size_t>(selected_)].folder);
  if (busy) ImGui::EndDisabled();
  ImGui::SameLine();
  const ImGuiStyle& style = ImGui::GetStyle();
  ImGui::SetNextItemWidth(std::max(80.0f, ImGui::GetContentRegionAvail().x - ImGui::CalcTextSize("zip").x -
                                              ImGui::GetFrameHeight() - style.ItemInnerSpacing.x -
                                              2.0f * style.ItemSpacing.x - 4.0f));
  ImGui::InputText("##export_folder", export_folder_.data(), export_folder_.size());
  ImGui::SameLine();
  ImGui::Checkbox("zip", &export_archive_);
  if (!chosen) ImGui::EndDisabled();
  if (busy) {
    ImGui::TextColored(to_vec4(colours::accent), "Exporting...");
  } else if (!export_result_.empty()) {
    ImGui::PushStyleColor(ImGuiCol_Text, to_vec4(export_failed_ ? colours::state_failed : colours::recommended));
    ImGui::TextWrapped("%s", export_result_.c_str());
    ImGui::PopStyleColor();
  }
}

void RecordingPanel::scan_if_due() {
  const auto now = Clock::now();
  if (now < next_scan_) return;
  next_scan_ = now + kScanPeriod;
  const fs::path root(folder_.data());
  std::error_code error;
  free_bytes_.reset();
  free_error_.clear();
  try {
    // The first existing parent: the folder is created when recording starts.
    fs::path probe = root;
    while (!probe.empty() && !fs::exists(probe, error)) probe = probe.parent_path();
    free_bytes_ = free_bytes(probe.empty() ? fs::path(".") : probe);
  } catch (const std::exception& e) {
    free_error_ = "free space unknown";
  }
  const std::string selected_folder =
      selected_ >= 0 && selected_ < static_cast<int>(sessions_.size()) ? sessions_[static_cast<std::size_t>(selected_)].folder.string() : "";
  sessions_.clear();
  selected_ = -1;
  if (!fs::is_directory(root, error)) return;
  for (const fs::directory_entry& entry : fs::directory_iterator(root, error)) {
    if (!entry.is_directory(error) || !is_session_folder(entry.path())) continue;
    try {
      sessions_.push_back({entry.path(), read_session_metadata(entry.path())});
    } catch (const std::exception&) {
      // A session being written by another process or damaged: `nirslam recover` deals with it.
    }
  }
  std::sort(sessions_.begin(), sessions_.end(),
            [](const SessionEntry& a, const SessionEntry& b) { return a.folder.filename() > b.folder.filename(); });
  for (std::size_t i = 0; i < sessions_.size(); ++i)
    if (sessions_[i].folder.string() == selected_folder) selected_ = static_cast<int>(i);
}

void RecordingPanel::start_export(const fs::path& session) {
  const fs::path out(export_folder_.data());
  ExportOptions options;
  options.archive = export_archive_;
  export_result_.clear();
  export_failed_ = false;
  export_job_ = std::async(std::launch::async, [session, out, options] {
    const ExportSummary summary = export_session(session, out, options);
    return fmt::format("Exported {} frames to {}{}{}", summary.frames, summary.folder.string(),
                       summary.archive ? " and " + summary.archive->string() : std::string(),
                       summary.evaluation.empty() ? std::string() : " · " + summary.evaluation);
  });
}

void RecordingPanel::collect_export() {
  if (!export_job_.valid() || export_job_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return;
  try {
    export_result_ = export_job_.get();
    export_failed_ = false;
  } catch (const std::exception& e) {
    export_result_ = std::string("Export failed: ") + e.what();
    export_failed_ = true;
  }
  if (on_export_done) on_export_done(!export_failed_, export_result_);
}

}  // namespace nirslam::ui
