#include "nirslam/capture/v4l2_camera.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <sstream>

#include "nirslam/capture/v4l2_io.hpp"

namespace nirslam {
namespace {

bool gone(int error_number) { return error_number == ENODEV || error_number == EIO || error_number == ENXIO; }

std::string frame_size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

std::string offered_formats(const DeviceInfo& info) {
  std::string list;
  for (const FormatInfo& f : info.formats) list += (list.empty() ? "" : ", ") + f.name + (f.supported ? "" : " (not convertible)");
  return list.empty() ? "none" : list;
}

std::string offered_sizes(const FormatInfo& format) {
  std::string list;
  for (const FrameSizeInfo& s : format.sizes) list += (list.empty() ? "" : ", ") + frame_size_text(s.width, s.height);
  return list.empty() ? "none listed" : list;
}

}  // namespace

V4l2Camera::V4l2Camera(std::shared_ptr<V4l2Io> io, std::string node) : io_(std::move(io)), node_(std::move(node)) {
  info_ = describe_device(*io_, node_);  // throws naming the node when it cannot be opened
  if (!info_.can_stream && !info_.can_read)
    throw InputError(node_, "capabilities", "the device offers neither streaming nor read() I/O");
  fd_ = io_->open(node_, O_RDWR | O_NONBLOCK);
  if (fd_ < 0) {
    const int e = errno;
    if (gone(e) || e == ENOENT) throw DeviceGoneError(node_, "open", "the device went away: " + std::string(std::strerror(e)));
    throw InputError(node_, "open", std::strerror(e));
  }
}

V4l2Camera::~V4l2Camera() {
  try {
    stop();
  } catch (...) {
    // An unplugged device fails STREAMOFF; the buffers are released all the same.
  }
  release_buffers();
  if (fd_ >= 0) io_->close(fd_);
}

void V4l2Camera::fail(const std::string& field, const std::string& message, int error_number) {
  if (gone(error_number)) throw DeviceGoneError(node_, field, "the device went away (unplugged): " + message);
  if (error_number == EBUSY)
    throw InputError(node_, field, "device is busy: another program is streaming from it (" + message + ")");
  throw InputError(node_, field, message + ": " + std::strerror(error_number));
}

int V4l2Camera::xioctl(unsigned long request, void* argument, const char* what) {
  int result;
  do {
    result = io_->ioctl(fd_, request, argument);
  } while (result < 0 && errno == EINTR);
  if (result < 0) fail(what, std::string(what) + " failed", errno);
  return result;
}

NegotiatedFormat V4l2Camera::configure(const StreamRequest& request) {
  if (streaming_) stop();
  release_buffers();

  // The format: the one asked for, or the first the device offers that nirslam can convert.
  const FormatInfo* chosen = nullptr;
  if (request.format) {
    for (const FormatInfo& f : info_.formats)
      if (f.fourcc == fourcc_of(*request.format)) chosen = &f;
    if (chosen == nullptr)
      throw InputError(node_, "format", std::string(to_string(*request.format)) + " is not offered; the device offers " +
                                            offered_formats(info_));
  } else {
    for (const FormatInfo& f : info_.formats)
      if (f.supported && chosen == nullptr) chosen = &f;
    if (chosen == nullptr)
      throw InputError(node_, "format", "no format nirslam can convert (GREY, Y10, Y12, Y16, YUYV, MJPG); the device offers " +
                                            offered_formats(info_));
  }
  if (!chosen->supported)
    throw InputError(node_, "format", chosen->name + " cannot be converted; use GREY, Y10, Y12, Y16, YUYV or MJPG");
  const PixelFormat format = *pixel_format_from_fourcc(chosen->fourcc);

  int width = request.width, height = request.height;
  if (width <= 0 || height <= 0) {
    if (chosen->sizes.empty()) throw InputError(node_, "size", chosen->name + " lists no frame size; give size=WxH");
    width = chosen->sizes.front().width;
    height = chosen->sizes.front().height;
  } else if (!chosen->sizes.empty()) {
    bool listed = false;
    for (const FrameSizeInfo& s : chosen->sizes) listed = listed || (s.width == width && s.height == height);
    if (!listed)
      throw InputError(node_, "size", frame_size_text(width, height) + " is not offered in " + chosen->name + "; sizes: " +
                                          offered_sizes(*chosen));
  }

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.pixelformat = chosen->fourcc;
  fmt.fmt.pix.width = static_cast<std::uint32_t>(width);
  fmt.fmt.pix.height = static_cast<std::uint32_t>(height);
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  xioctl(VIDIOC_S_FMT, &fmt, "format");
  // Drivers adjust instead of refusing: what came back is what will stream.
  if (fmt.fmt.pix.pixelformat != chosen->fourcc)
    throw InputError(node_, "format", "the driver would not take " + chosen->name + " (it chose " +
                                          fourcc_to_string(fmt.fmt.pix.pixelformat) + ")");
  if (static_cast<int>(fmt.fmt.pix.width) != width || static_cast<int>(fmt.fmt.pix.height) != height)
    throw InputError(node_, "size", "the driver would not take " + frame_size_text(width, height) + " (it chose " +
                                        frame_size_text(static_cast<int>(fmt.fmt.pix.width), static_cast<int>(fmt.fmt.pix.height)) + ")");

  format_ = {};
  format_.layout = {format, width, height, static_cast<int>(fmt.fmt.pix.bytesperline)};
  format_.size_image = fmt.fmt.pix.sizeimage;
  if (request.fps > 0.0) {
    format_.fps = set_frame_rate(request.fps);
  } else {
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (io_->ioctl(fd_, VIDIOC_G_PARM, &parm) == 0 && parm.parm.capture.timeperframe.numerator > 0)
      format_.fps = rate_from_interval(parm.parm.capture.timeperframe.numerator, parm.parm.capture.timeperframe.denominator);
  }

  if (!info_.can_stream) {
    format_.uses_read = true;
    read_buffer_.assign(format_.size_image, 0);
    return format_;
  }
  if (request.buffer_count < 1 || request.buffer_count > 32)
    throw InputError(node_, "buffers", std::to_string(request.buffer_count) + " buffers requested; give 1..32");
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(request.buffer_count);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  xioctl(VIDIOC_REQBUFS, &req, "buffers");
  if (req.count < 1) throw InputError(node_, "buffers", "the driver granted no buffers");
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    xioctl(VIDIOC_QUERYBUF, &buf, "buffers");
    void* start = io_->mmap(buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
    if (start == MAP_FAILED) fail("buffers", "mmap of buffer " + std::to_string(i), errno);
    buffers_.push_back({start, buf.length});
  }
  format_.buffer_count = static_cast<int>(buffers_.size());
  return format_;
}

void V4l2Camera::release_buffers() {
  for (const MappedBuffer& b : buffers_) io_->munmap(b.start, b.length);
  const bool had_buffers = !buffers_.empty();
  buffers_.clear();
  if (had_buffers && fd_ >= 0) {
    v4l2_requestbuffers req{};
    req.count = 0;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    io_->ioctl(fd_, VIDIOC_REQBUFS, &req);  // best effort: an unplugged device has nothing to free
  }
}

void V4l2Camera::start() {
  if (streaming_) return;
  if (format_.layout.width == 0) throw InputError(node_, "format", "start() before configure()");
  if (!format_.uses_read) {
    for (std::size_t i = 0; i < buffers_.size(); ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = static_cast<std::uint32_t>(i);
      xioctl(VIDIOC_QBUF, &buf, "stream");
    }
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(VIDIOC_STREAMON, &type, "stream");
  }
  streaming_ = true;
}

void V4l2Camera::stop() {
  if (!streaming_) return;
  streaming_ = false;
  if (!format_.uses_read) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(VIDIOC_STREAMOFF, &type, "stream");
  }
}

std::optional<CapturedImage> V4l2Camera::capture(int timeout_ms) {
  if (!streaming_) throw InputError(node_, "stream", "capture() while not streaming");
  if (!gone_message_.empty()) throw DeviceGoneError(node_, "stream", gone_message_);
  short revents = 0;
  const int ready = io_->poll(fd_, POLLIN, revents, timeout_ms);
  if (ready < 0) {
    if (errno == EINTR) return std::nullopt;
    fail("stream", "poll", errno);
  }
  if (ready == 0) return std::nullopt;
  if ((revents & (POLLERR | POLLHUP)) != 0 && (revents & POLLIN) == 0) {
    // The kernel reports an unplug as POLLERR/POLLHUP; the next ioctl tells ENODEV apart.
    v4l2_format probe{};
    probe.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (io_->ioctl(fd_, VIDIOC_G_FMT, &probe) < 0) fail("stream", "poll reported an error", errno);
    throw InputError(node_, "stream", "poll reported an error on a device that is still present");
  }

  CapturedImage out;
  if (format_.uses_read) {
    const std::ptrdiff_t n = io_->read(fd_, read_buffer_.data(), read_buffer_.size());
    if (n < 0) {
      if (errno == EAGAIN || errno == EINTR) return std::nullopt;
      fail("stream", "read", errno);
    }
    out.image = convert_buffer(format_.layout, std::span(read_buffer_.data(), static_cast<std::size_t>(n)));
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);  // read() gives no timestamp: the time it returned
    out.timestamp_s = now.tv_sec + now.tv_nsec * 1e-9;
    out.bit_depth = bit_depth_of(format_.layout.format);
    return out;
  }

  v4l2_buffer buf{};
  buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  if (io_->ioctl(fd_, VIDIOC_DQBUF, &buf) < 0) {
    if (errno == EAGAIN || errno == EINTR) return std::nullopt;
    fail("stream", "VIDIOC_DQBUF", errno);
  }
  if (buf.index >= buffers_.size()) throw InputError(node_, "stream", "the driver returned unknown buffer " + std::to_string(buf.index));
  const MappedBuffer& mapped = buffers_[buf.index];
  std::string conversion_error;
  try {
    if ((buf.flags & V4L2_BUF_FLAG_ERROR) == 0)
      out.image = convert_buffer(format_.layout, std::span(static_cast<const std::uint8_t*>(mapped.start),
                                                           std::min<std::size_t>(buf.bytesused, mapped.length)));
  } catch (const std::exception& e) {
    conversion_error = e.what();
  }
  out.sequence = buf.sequence;
  out.timestamp_s = static_cast<double>(buf.timestamp.tv_sec) + static_cast<double>(buf.timestamp.tv_usec) * 1e-6;
  out.bit_depth = bit_depth_of(format_.layout.format);
  // The buffer goes back before anything else can fail, so the driver never runs out of them.
  buf.flags = 0;
  if (io_->ioctl(fd_, VIDIOC_QBUF, &buf) < 0) {
    const int e = errno;
    // Unplugged right after this frame: the frame is good; the next capture() reports the unplug.
    if (gone(e)) gone_message_ = std::string("the device went away (unplugged): ") + std::strerror(e);
    else fail("stream", "VIDIOC_QBUF", e);
  }
  if (!conversion_error.empty()) throw InputError(node_, "frame " + std::to_string(out.sequence), conversion_error);
  if (out.image.empty()) return std::nullopt;  // a corrupted frame the driver flagged: skipped
  return out;
}

std::optional<ControlInfo> V4l2Camera::control(std::uint32_t id) {
  v4l2_queryctrl query{};
  query.id = id;
  if (io_->ioctl(fd_, VIDIOC_QUERYCTRL, &query) < 0) {
    if (gone(errno)) fail("controls", "VIDIOC_QUERYCTRL", errno);
    return std::nullopt;
  }
  if ((query.flags & V4L2_CTRL_FLAG_DISABLED) != 0) return std::nullopt;
  ControlInfo c;
  c.id = id;
  c.name = std::string(reinterpret_cast<const char*>(query.name), strnlen(reinterpret_cast<const char*>(query.name), sizeof query.name));
  c.minimum = query.minimum;
  c.maximum = query.maximum;
  c.step = std::max(1, query.step);
  c.default_value = query.default_value;
  c.is_menu = query.type == V4L2_CTRL_TYPE_MENU;
  c.is_boolean = query.type == V4L2_CTRL_TYPE_BOOLEAN;
  c.value = get_control(id);
  return c;
}

std::int32_t V4l2Camera::get_control(std::uint32_t id) {
  v4l2_control c{};
  c.id = id;
  xioctl(VIDIOC_G_CTRL, &c, "controls");
  return c.value;
}

std::int32_t V4l2Camera::set_control(std::uint32_t id, std::int32_t value) {
  const auto range = control(id);
  if (!range) throw InputError(node_, "control " + std::to_string(id), "the device has no such control");
  if (value < range->minimum || value > range->maximum)
    throw InputError(node_, range->name, std::to_string(value) + " is outside the device's range " +
                                             std::to_string(range->minimum) + ".." + std::to_string(range->maximum));
  v4l2_control c{};
  c.id = id;
  c.value = value;
  xioctl(VIDIOC_S_CTRL, &c, range->name.c_str());
  return get_control(id);
}

double V4l2Camera::set_frame_rate(double fps) {
  if (!(fps > 0.0) || !std::isfinite(fps)) throw InputError(node_, "fps", "frame rate must be positive");
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  xioctl(VIDIOC_G_PARM, &parm, "fps");
  if ((parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) == 0)
    throw InputError(node_, "fps", "the device does not let the frame rate be set");
  // Time per frame, 1/fps seconds, in 100 ns units as UVC keeps it.
  parm.parm.capture.timeperframe.numerator = static_cast<std::uint32_t>(std::lround(1e7 / fps));
  parm.parm.capture.timeperframe.denominator = 10000000;
  xioctl(VIDIOC_S_PARM, &parm, "fps");
  const auto& tpf = parm.parm.capture.timeperframe;
  format_.fps = tpf.numerator > 0 ? rate_from_interval(tpf.numerator, tpf.denominator) : fps;
  return format_.fps;
}

}  // namespace nirslam
