#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace nirslam {

class V4l2Io;

// One frame size a format offers, with the frame rates the device lists for it.
struct FrameSizeInfo {
  int width = 0;
  int height = 0;
  std::vector<double> rates_fps;  // from VIDIOC_ENUM_FRAMEINTERVALS, fastest first
};

struct FormatInfo {
  std::uint32_t fourcc = 0;
  std::string name;          // fourcc as text: "GREY", "Y16", "MJPG"
  std::string description;   // the driver's description
  bool supported = false;    // nirslam converts it (GREY, Y10, Y12, Y16, YUYV, MJPG)
  std::vector<FrameSizeInfo> sizes;
};

// A control as VIDIOC_QUERYCTRL reports it, in the device's units.
struct ControlInfo {
  std::uint32_t id = 0;
  std::string name;  // the driver's name: "Exposure, Absolute", "Gain"
  std::int32_t minimum = 0;
  std::int32_t maximum = 0;
  std::int32_t step = 1;
  std::int32_t default_value = 0;
  std::int32_t value = 0;  // current value (VIDIOC_G_CTRL)
  bool is_menu = false;
  bool is_boolean = false;
};

struct DeviceInfo {
  std::string node;      // "/dev/video0"
  std::string card;      // the product name
  std::string driver;    // "uvcvideo"
  std::string bus_info;  // "usb-0000:00:14.0-2"
  bool can_stream = false;  // V4L2_CAP_STREAMING (memory-mapped buffers)
  bool can_read = false;    // V4L2_CAP_READWRITE
  std::vector<FormatInfo> formats;
  std::vector<ControlInfo> controls;
  std::string error;  // why the node could not be described (busy, permission), empty when it could
};

// Every video capture node the seam lists, described. Nodes that are not capture devices (the
// UVC metadata node next to each camera) are left out; a node that cannot be opened or queried is
// listed with its error rather than failing the whole listing.
std::vector<DeviceInfo> enumerate_devices(V4l2Io& io);

// One node, described. Throws nirslam::InputError naming the node when it cannot be opened or
// is not a video capture device.
DeviceInfo describe_device(V4l2Io& io, const std::string& node);

// Frames per second from a V4L2 time per frame (numerator / denominator seconds), rounded to
// 0.001 fps: UVC keeps intervals in 100 ns units, so 30 fps comes back as 333333 / 10^7 s.
// 0 when the numerator is 0.
double rate_from_interval(std::uint32_t numerator, std::uint32_t denominator);

// The capture controls nirslam drives, by their V4L2 ids.
const ControlInfo* find_control(const std::vector<ControlInfo>& controls, std::uint32_t id);

}  // namespace nirslam
