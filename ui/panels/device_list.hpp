#pragma once

#include <optional>
#include <string>
#include <vector>

#include "nirslam/capture/device_info.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// The camera picker the session panel embeds: the V4L2 devices (node, name, bus), and for the
// selected one its formats, frame sizes and rates to choose from; "Open" gives the source string
// ("v4l2:/dev/video0?format=Y16&size=640x480&fps=30", or "v4l2-emulated:..." for the emulated
// driver) for the caller to open. Devices that could not be described show their error.
class DeviceList {
public:
  // Draws into the current ImGui window; returns the source string on the frame Open is pressed.
  std::optional<std::string> draw(const std::vector<DeviceInfo>& devices, bool emulated);

  // The source string for the current choice, std::nullopt when nothing usable is selected.
  std::optional<std::string> selected_source(const std::vector<DeviceInfo>& devices, bool emulated) const;

  // The choice, by index into the lists of the last draw().
  int device = 0;
  int format = 0;  // among the device's convertible formats
  int size = 0;
  int rate = 0;
  bool stereo_side_by_side = false;

  // Rows of the device table, for the screenshot tests.
  const std::vector<ScreenRect>& device_rows() const { return rows_; }
  const ScreenRect& open_button_rect() const { return open_button_; }

private:
  std::vector<ScreenRect> rows_;
  ScreenRect open_button_;
};

// The formats of `device` that nirslam converts, in the device's order.
std::vector<const FormatInfo*> convertible_formats(const DeviceInfo& device);

}  // namespace nirslam::ui
