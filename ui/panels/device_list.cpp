#include "ui/panels/device_list.hpp"

#include <algorithm>

#include <fmt/format.h>
#include <imgui.h>

#include "ui/theme.hpp"

namespace nirslam::ui {

std::vector<const FormatInfo*> convertible_formats(const DeviceInfo& device) {
  std::vector<const FormatInfo*> formats;
  for (const FormatInfo& f : device.formats)
    if (f.supported && !f.sizes.empty()) formats.push_back(&f);
  return formats;
}

std::optional<std::string> DeviceList::selected_source(const std::vector<DeviceInfo>& devices, bool emulated) const {
  if (device < 0 || device >= static_cast<int>(devices.size()) || !devices[device].error.empty()) return std::nullopt;
  const DeviceInfo& d = devices[device];
  const auto formats = convertible_formats(d);
  if (format < 0 || format >= static_cast<int>(formats.size())) return std::nullopt;
  const FormatInfo& f = *formats[format];
  if (size < 0 || size >= static_cast<int>(f.sizes.size())) return std::nullopt;
  const FrameSizeInfo& s = f.sizes[size];
  std::string text = fmt::format("{}{}?format={}&size={}x{}", emulated ? "v4l2-emulated:" : "v4l2:", d.node, f.name, s.width, s.height);
  if (rate >= 0 && rate < static_cast<int>(s.rates_fps.size())) text += fmt::format("&fps={:g}", s.rates_fps[rate]);
  text += stereo_side_by_side ? "&stereo=sbs" : (emulated && d.node == "/dev/video2" ? "&stereo=none" : "");
  return text;
}

std::optional<std::string> DeviceList::draw(const std::vector<DeviceInfo>& devices, bool emulated) {
  rows_.clear();
  open_button_ = {};
  if (devices.empty()) {
    ImGui::TextColored(to_vec4(colours::text_dim), "No cameras found (/dev/video*).");
    return std::nullopt;
  }
  device = std::clamp(device, 0, static_cast<int>(devices.size()) - 1);
  for (int i = 0; i < static_cast<int>(devices.size()); ++i) {
    const DeviceInfo& d = devices[i];
    const std::string label = d.error.empty() ? fmt::format("{}  {}  ({})##device{}", d.node, d.card, d.bus_info, i)
                                              : fmt::format("{}  unavailable##device{}", d.node, i);
    if (ImGui::Selectable(label.c_str(), device == i) && device != i) {
      device = i;
      format = size = rate = 0;
      stereo_side_by_side = emulated && d.node == "/dev/video2";
    }
    rows_.push_back({ImGui::GetItemRectMin(), ImGui::GetItemRectMax()});
    if (!d.error.empty()) ImGui::TextColored(to_vec4(colours::state_failed), "  %s", d.error.c_str());
  }
  const DeviceInfo& d = devices[device];
  const auto formats = convertible_formats(d);
  if (!d.error.empty() || formats.empty()) {
    if (d.error.empty()) ImGui::TextColored(to_vec4(colours::state_failed), "%s offers no format nirslam converts", d.node.c_str());
    return std::nullopt;
  }
  format = std::clamp(format, 0, static_cast<int>(formats.size()) - 1);
  const FormatInfo& f = *formats[format];
  size = std::clamp(size, 0, static_cast<int>(f.sizes.size()) - 1);
  const FrameSizeInfo& s = f.sizes[size];
  rate = s.rates_fps.empty() ? 0 : std::clamp(rate, 0, static_cast<int>(s.rates_fps.size()) - 1);

  ImGui::PushItemWidth(std::min(220.0f, ImGui::GetContentRegionAvail().x * 0.6f));
  if (ImGui::BeginCombo("Format", fmt::format("{} ({})", f.name, f.description).c_str())) {
    for (int i = 0; i < static_cast<int>(formats.size()); ++i)
      if (ImGui::Selectable(fmt::format("{} ({})", formats[i]->name, formats[i]->description).c_str(), i == format)) {
        format = i;
        size = rate = 0;
      }
    ImGui::EndCombo();
  }
  if (ImGui::BeginCombo("Size", fmt::format("{}x{}", s.width, s.height).c_str())) {
    for (int i = 0; i < static_cast<int>(f.sizes.size()); ++i)
      if (ImGui::Selectable(fmt::format("{}x{}", f.sizes[i].width, f.sizes[i].height).c_str(), i == size)) {
        size = i;
        rate = 0;
      }
    ImGui::EndCombo();
  }
  const std::string rate_label = s.rates_fps.empty() ? std::string("device rate") : fmt::format("{:g} fps", s.rates_fps[rate]);
  if (ImGui::BeginCombo("Rate", rate_label.c_str())) {
    for (int i = 0; i < static_cast<int>(s.rates_fps.size()); ++i)
      if (ImGui::Selectable(fmt::format("{:g} fps", s.rates_fps[i]).c_str(), i == rate)) rate = i;
    ImGui::EndCombo();
  }
  ImGui::PopItemWidth();
  ImGui::Checkbox("Side-by-side stereo (left view to SLAM)", &stereo_side_by_side);
  const bool open = ImGui::Button("Open camera");
  open_button_ = {ImGui::GetItemRectMin(), ImGui::GetItemRectMax()};
  return open ? selected_source(devices, emulated) : std::nullopt;
}

}  // namespace nirslam::ui
