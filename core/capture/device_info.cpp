#include "nirslam/capture/device_info.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "nirslam/capture/pixel_format.hpp"
#include "nirslam/capture/v4l2_io.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

std::string text_of(const std::uint8_t* bytes, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(bytes), strnlen(reinterpret_cast<const char*>(bytes), size));
}

// Closes the descriptor on every path out.
struct OpenNode {
  V4l2Io& io;
  int fd;
  ~OpenNode() {
    if (fd >= 0) io.close(fd);
  }
};

std::vector<double> rates_of(V4l2Io& io, int fd, std::uint32_t fourcc, int width, int height) {
  std::vector<double> rates;
  v4l2_frmivalenum interval{};
  interval.pixel_format = fourcc;
  interval.width = static_cast<std::uint32_t>(width);
  interval.height = static_cast<std::uint32_t>(height);
  for (interval.index = 0; io.ioctl(fd, VIDIOC_ENUM_FRAMEINTERVALS, &interval) == 0; ++interval.index) {
    if (interval.type == V4L2_FRMIVAL_TYPE_DISCRETE) {
      if (interval.discrete.numerator > 0)
        rates.push_back(rate_from_interval(interval.discrete.numerator, interval.discrete.denominator));
    } else {  // a continuous or stepwise range: its ends
      if (interval.stepwise.min.numerator > 0)
        rates.push_back(rate_from_interval(interval.stepwise.min.numerator, interval.stepwise.min.denominator));
      if (interval.stepwise.max.numerator > 0)
        rates.push_back(rate_from_interval(interval.stepwise.max.numerator, interval.stepwise.max.denominator));
      break;
    }
  }
  std::sort(rates.begin(), rates.end(), std::greater<>());
  return rates;
}

std::vector<FrameSizeInfo> sizes_of(V4l2Io& io, int fd, std::uint32_t fourcc) {
  std::vector<FrameSizeInfo> sizes;
  v4l2_frmsizeenum size{};
  size.pixel_format = fourcc;
  for (size.index = 0; io.ioctl(fd, VIDIOC_ENUM_FRAMESIZES, &size) == 0; ++size.index) {
    if (size.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
      const int w = static_cast<int>(size.discrete.width), h = static_cast<int>(size.discrete.height);
      sizes.push_back({w, h, rates_of(io, fd, fourcc, w, h)});
    } else {  // stepwise: the largest size stands for the range
      const int w = static_cast<int>(size.stepwise.max_width), h = static_cast<int>(size.stepwise.max_height);
      sizes.push_back({w, h, rates_of(io, fd, fourcc, w, h)});
      break;
    }
  }
  return sizes;
}

std::vector<ControlInfo> controls_of(V4l2Io& io, int fd) {
  std::vector<ControlInfo> controls;
  v4l2_queryctrl query{};
  query.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  while (io.ioctl(fd, VIDIOC_QUERYCTRL, &query) == 0) {
    if ((query.flags & V4L2_CTRL_FLAG_DISABLED) == 0 && query.type != V4L2_CTRL_TYPE_CTRL_CLASS) {
      ControlInfo c;
      c.id = query.id;
      c.name = text_of(query.name, sizeof query.name);
      c.minimum = query.minimum;
      c.maximum = query.maximum;
      c.step = std::max(1, query.step);
      c.default_value = query.default_value;
      c.is_menu = query.type == V4L2_CTRL_TYPE_MENU;
      c.is_boolean = query.type == V4L2_CTRL_TYPE_BOOLEAN;
      v4l2_control value{};
      value.id = query.id;
      c.value = io.ioctl(fd, VIDIOC_G_CTRL, &value) == 0 ? value.value : query.default_value;
      controls.push_back(std::move(c));
    }
    query.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  return controls;
}

}  // namespace

DeviceInfo describe_device(V4l2Io& io, const std::string& node) {
  const OpenNode open{io, io.open(node, O_RDWR | O_NONBLOCK)};
  if (open.fd < 0) {
    const int e = errno;
    throw InputError(node, "open", e == EBUSY ? "device is busy (another program has it open)"
                                              : "cannot open: " + std::string(std::strerror(e)));
  }
  v4l2_capability cap{};
  if (io.ioctl(open.fd, VIDIOC_QUERYCAP, &cap) != 0)
    throw InputError(node, "VIDIOC_QUERYCAP", "not a V4L2 device: " + std::string(std::strerror(errno)));
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0)
    throw InputError(node, "capabilities", "not a video capture device (a metadata or output node)");

  DeviceInfo info;
  info.node = node;
  info.card = text_of(cap.card, sizeof cap.card);
  info.driver = text_of(cap.driver, sizeof cap.driver);
  info.bus_info = text_of(cap.bus_info, sizeof cap.bus_info);
  info.can_stream = (caps & V4L2_CAP_STREAMING) != 0;
  info.can_read = (caps & V4L2_CAP_READWRITE) != 0;

  v4l2_fmtdesc desc{};
  desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  for (desc.index = 0; io.ioctl(open.fd, VIDIOC_ENUM_FMT, &desc) == 0; ++desc.index) {
    if ((desc.flags & V4L2_FMT_FLAG_EMULATED) != 0) continue;  // libv4l2's RGB conversions: not the camera's
    FormatInfo format;
    format.fourcc = desc.pixelformat;
    format.name = fourcc_to_string(desc.pixelformat);
    format.description = text_of(desc.description, sizeof desc.description);
    format.supported = pixel_format_from_fourcc(desc.pixelformat).has_value();
    format.sizes = sizes_of(io, open.fd, desc.pixelformat);
    info.formats.push_back(std::move(format));
  }
  info.controls = controls_of(io, open.fd);
  return info;
}

std::vector<DeviceInfo> enumerate_devices(V4l2Io& io) {
  std::vector<DeviceInfo> devices;
  for (const std::string& node : io.device_nodes()) {
    try {
      devices.push_back(describe_device(io, node));
    } catch (const InputError& e) {
      if (e.field() == "capabilities") continue;  // not a camera: the metadata node beside each UVC camera
      DeviceInfo unavailable;
      unavailable.node = node;
      unavailable.error = e.what();
      devices.push_back(std::move(unavailable));
    }
  }
  return devices;
}

double rate_from_interval(std::uint32_t numerator, std::uint32_t denominator) {
  if (numerator == 0) return 0.0;
  return std::round(1000.0 * denominator / numerator) / 1000.0;
}

const ControlInfo* find_control(const std::vector<ControlInfo>& controls, std::uint32_t id) {
  const auto it = std::find_if(controls.begin(), controls.end(), [id](const ControlInfo& c) { return c.id == id; });
  return it == controls.end() ? nullptr : &*it;
}

}  // namespace nirslam
