#include "nirslam/capture/emulated_uvc.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>
#include <stdexcept>

namespace nirslam {

using Clock = std::chrono::steady_clock;

struct EmulatedUvc::Device {
  explicit Device(EmulatedCameraSpec s) : spec(std::move(s)) {
    if (spec.formats.empty() || spec.formats.front().sizes.empty() || spec.formats.front().rates_fps.empty())
      throw std::invalid_argument("emulated camera " + spec.node + ": needs a format with a size and a rate");
    const EmulatedFormat& first = spec.formats.front();
    set_layout(first.format, first.sizes.front().first, first.sizes.front().second);
    fps = first.rates_fps.front();
    exposure = spec.exposure_default;
    gain = spec.gain_default;
    auto_exposure = spec.auto_exposure_default;
  }

  void set_layout(PixelFormat format, int width, int height) {
    layout = {format, width, height, width * bytes_per_pixel(format)};
    size_image = format == PixelFormat::Mjpg ? static_cast<std::uint32_t>(width * height * 2 + 4096)
                                             : static_cast<std::uint32_t>(layout.bytes_per_line * height);
  }

  struct Buffer {
    std::shared_ptr<std::vector<std::uint8_t>> memory;
    bool queued = false;
    bool done = false;
    std::uint32_t bytes_used = 0;
    std::uint32_t sequence = 0;
    double timestamp_s = 0.0;
  };

  EmulatedCameraSpec spec;
  bool plugged = true;
  BufferLayout layout;
  std::uint32_t size_image = 0;
  double fps = 30.0;
  std::int32_t exposure = 0;
  std::int32_t gain = 0;
  bool auto_exposure = false;

  int owner_fd = -1;  // the descriptor that holds the buffers (and the stream)
  bool busy_elsewhere = false;
  bool hold = false;
  long long allowed = -1;  // frames that may still become ready; negative: unlimited
  std::set<std::uint32_t> dropped;
  int unplug_countdown = -1;
  std::vector<Buffer> buffers;
  std::deque<int> queued;  // buffer indices waiting to be filled, in order
  std::deque<int> done;    // filled, waiting for DQBUF
  bool streaming = false;
  Clock::time_point stream_start;
  std::uint32_t next_sequence = 0;
  int delivered = 0;
  std::map<std::uint32_t, std::pair<std::int32_t, std::int32_t>> used;

  double period_s() const { return 1.0 / fps; }

  // The camera's own auto exposure: half-way each frame towards the exposure that puts the wall
  // at mid-grey at this gain, on the control's step and range.
  void run_auto_exposure() {
    if (!auto_exposure) return;
    const double target = 100.0 * 16.0 / std::max(1, gain);
    double next = exposure + 0.5 * (target - exposure);
    next = spec.exposure_min + std::round((next - spec.exposure_min) / spec.exposure_step) * spec.exposure_step;
    exposure = static_cast<std::int32_t>(std::clamp(next, double(spec.exposure_min), double(spec.exposure_max)));
  }

  // Draws frame `sequence` into `bytes`; returns the bytes used.
  std::size_t draw(std::uint32_t sequence, std::span<std::uint8_t> bytes) {
    run_auto_exposure();
    EmulatedFrameRequest request{sequence, timestamp_of(sequence), layout, exposure, gain};
    used[sequence] = {exposure, gain};
    return spec.generator ? spec.generator(request, bytes) : draw_emulated_pattern(request, spec.side_by_side, bytes);
  }

  double timestamp_of(std::uint32_t sequence) const { return spec.first_timestamp_s + sequence * period_s(); }

  std::uint32_t skip_dropped(std::uint32_t sequence) const {
    while (dropped.count(sequence) != 0) ++sequence;
    return sequence;
  }

  bool may_produce() const { return plugged && streaming && !hold && allowed != 0; }

  void fill_next(int index) {
    if (allowed > 0) --allowed;
    next_sequence = skip_dropped(next_sequence);
    Buffer& b = buffers[index];
    b.bytes_used = static_cast<std::uint32_t>(draw(next_sequence, *b.memory));
    b.sequence = next_sequence;
    b.timestamp_s = timestamp_of(next_sequence);
    b.queued = false;
    b.done = true;
    done.push_back(index);
    ++next_sequence;
  }

  // Fills buffers with the frames that are due. Unpaced: one frame whenever none waits and a
  // buffer is queued. Paced: every frame whose time has come; with no buffer queued for it, the
  // frame is lost as in a UVC driver, and the sequence number jumps.
  void produce() {
    if (!may_produce()) return;
    if (!spec.paced) {
      if (done.empty() && !queued.empty()) {
        const int index = queued.front();
        queued.pop_front();
        fill_next(index);
      }
      return;
    }
    const double elapsed = std::chrono::duration<double>(Clock::now() - stream_start).count();
    const auto due = static_cast<std::uint32_t>(std::floor(elapsed / period_s())) + 1;
    while (skip_dropped(next_sequence) < due && allowed != 0) {
      if (queued.empty()) {
        next_sequence = skip_dropped(next_sequence) + 1;
        continue;
      }
      const int index = queued.front();
      queued.pop_front();
      fill_next(index);
    }
  }

  Clock::time_point next_due() const {
    return stream_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(next_sequence * period_s()));
  }

  void stop_streaming() {
    streaming = false;
    queued.clear();
    done.clear();
    for (Buffer& b : buffers) b.queued = b.done = false;
  }

  // A delivered frame counts towards a scripted unplug.
  void count_delivery() {
    ++delivered;
    if (unplug_countdown > 0 && --unplug_countdown == 0) plugged = false;
  }
};

struct EmulatedUvc::Handle {
  std::shared_ptr<Device> device;
  bool nonblocking = false;
};

namespace {

int fail(int error_number) {
  errno = error_number;
  return -1;
}

void copy_name(std::uint8_t* out, std::size_t size, const std::string& text) {
  std::memset(out, 0, size);
  std::memcpy(out, text.data(), std::min(size - 1, text.size()));
}

constexpr std::uint32_t kControlOrder[] = {V4L2_CID_GAIN, V4L2_CID_EXPOSURE_AUTO, V4L2_CID_EXPOSURE_ABSOLUTE};
constexpr std::int64_t kBufferOffsetUnit = 1 << 20;  // the "page offset" QUERYBUF hands out per buffer

}  // namespace

EmulatedUvc::EmulatedUvc() = default;
EmulatedUvc::~EmulatedUvc() = default;

void EmulatedUvc::add_camera(EmulatedCameraSpec spec) {
  auto device = std::make_shared<Device>(std::move(spec));
  const std::lock_guard lock(mutex_);
  devices_[device->spec.node] = device;
}

std::shared_ptr<EmulatedUvc::Device> EmulatedUvc::device_of(const std::string& node) const {
  const auto it = devices_.find(node);
  if (it == devices_.end()) throw std::invalid_argument("emulated driver: no camera at " + node);
  return it->second;
}

void EmulatedUvc::drop_sequences(const std::string& node, std::set<std::uint32_t> dropped) {
  const std::lock_guard lock(mutex_);
  device_of(node)->dropped = std::move(dropped);
}

void EmulatedUvc::unplug_after(const std::string& node, int frames) {
  {
    const std::lock_guard lock(mutex_);
    auto device = device_of(node);
    if (frames <= 0) device->plugged = false;
    else device->unplug_countdown = frames;
  }
  changed_.notify_all();
}

void EmulatedUvc::replug(const std::string& node) {
  {
    const std::lock_guard lock(mutex_);
    // A new device instance: descriptors opened before the unplug stay dead (ENODEV). The test's
    // scripts for frames (allowance, hold) carry over; the device's own state starts afresh.
    const auto old = device_of(node);
    auto fresh = std::make_shared<Device>(old->spec);
    fresh->allowed = old->allowed;
    fresh->hold = old->hold;
    devices_[node] = fresh;
  }
  changed_.notify_all();
}

void EmulatedUvc::set_busy_elsewhere(const std::string& node, bool busy) {
  const std::lock_guard lock(mutex_);
  device_of(node)->busy_elsewhere = busy;
}

void EmulatedUvc::hold_frames(const std::string& node, bool hold) {
  {
    const std::lock_guard lock(mutex_);
    device_of(node)->hold = hold;
  }
  changed_.notify_all();
}

void EmulatedUvc::allow_frames(const std::string& node, int frames) {
  {
    const std::lock_guard lock(mutex_);
    auto device = device_of(node);
    device->allowed = frames < 0 ? -1 : std::max(0LL, device->allowed) + frames;
  }
  changed_.notify_all();
}

void EmulatedUvc::limit_frames(const std::string& node, int frames) {
  {
    const std::lock_guard lock(mutex_);
    device_of(node)->allowed = frames;
  }
  changed_.notify_all();
}

int EmulatedUvc::frames_delivered(const std::string& node) const {
  const std::lock_guard lock(mutex_);
  return device_of(node)->delivered;
}

std::map<std::uint32_t, std::pair<std::int32_t, std::int32_t>> EmulatedUvc::exposures_used(const std::string& node) const {
  const std::lock_guard lock(mutex_);
  return device_of(node)->used;
}

bool EmulatedUvc::plugged(const std::string& node) const {
  const std::lock_guard lock(mutex_);
  return device_of(node)->plugged;
}

std::vector<std::string> EmulatedUvc::device_nodes() {
  const std::lock_guard lock(mutex_);
  std::vector<std::string> nodes;
  for (const auto& [node, device] : devices_)
    if (device->plugged) nodes.push_back(node);
  return nodes;
}

int EmulatedUvc::open(const std::string& path, int flags) {
  const std::lock_guard lock(mutex_);
  const auto it = devices_.find(path);
  if (it == devices_.end() || !it->second->plugged) return fail(ENOENT);
  const int fd = next_fd_++;
  handles_[fd] = std::make_shared<Handle>(Handle{it->second, (flags & O_NONBLOCK) != 0});
  return fd;
}

int EmulatedUvc::close(int fd) {
  {
    const std::lock_guard lock(mutex_);
    const auto it = handles_.find(fd);
    if (it == handles_.end()) return fail(EBADF);
    Device& d = *it->second->device;
    if (d.owner_fd == fd) {
      d.stop_streaming();
      d.owner_fd = -1;
      d.buffers.clear();  // mappings keep their memory alive until munmap
    }
    handles_.erase(it);
  }
  changed_.notify_all();
  return 0;
}

void* EmulatedUvc::mmap(std::size_t length, int /*protection*/, int /*flags*/, int fd, std::int64_t offset) {
  const std::lock_guard lock(mutex_);
  const auto it = handles_.find(fd);
  if (it == handles_.end()) {
    errno = EBADF;
    return MAP_FAILED;
  }
  Device& d = *it->second->device;
  if (!d.plugged) {
    errno = ENODEV;
    return MAP_FAILED;
  }
  const std::int64_t index = offset / kBufferOffsetUnit;
  if (offset % kBufferOffsetUnit != 0 || index < 0 || index >= static_cast<std::int64_t>(d.buffers.size()) ||
      length > d.buffers[index].memory->size()) {
    errno = EINVAL;
    return MAP_FAILED;
  }
  return d.buffers[index].memory->data();
}

int EmulatedUvc::munmap(void* /*address*/, std::size_t /*length*/) { return 0; }

int EmulatedUvc::ioctl(int fd, unsigned long request, void* argument) {
  std::unique_lock lock(mutex_);
  const auto it = handles_.find(fd);
  if (it == handles_.end()) return fail(EBADF);
  const auto handle = it->second;
  Device& d = *handle->device;
  if (!d.plugged) return fail(ENODEV);
  const bool owner = d.owner_fd == fd;
  const bool busy = d.busy_elsewhere || (d.owner_fd >= 0 && !owner);

  auto find_format = [&](std::uint32_t fourcc) -> const EmulatedFormat* {
    for (const EmulatedFormat& f : d.spec.formats)
      if (fourcc_of(f.format) == fourcc) return &f;
    return nullptr;
  };
  // The driver adjusts rather than refuses: an unknown fourcc becomes its first format, a size
  // the nearest it offers (by area).
  auto adjust = [&](v4l2_pix_format& pix) {
    const EmulatedFormat* f = find_format(pix.pixelformat);
    if (f == nullptr) f = &d.spec.formats.front();
    auto best = f->sizes.front();
    for (const auto& s : f->sizes)
      if (std::abs(static_cast<long>(s.first) * s.second - static_cast<long>(pix.width) * pix.height) <
          std::abs(static_cast<long>(best.first) * best.second - static_cast<long>(pix.width) * pix.height))
        best = s;
    Device probe(d.spec);
    probe.set_layout(f->format, best.first, best.second);
    pix.pixelformat = fourcc_of(f->format);
    pix.width = static_cast<std::uint32_t>(best.first);
    pix.height = static_cast<std::uint32_t>(best.second);
    pix.field = V4L2_FIELD_NONE;
    pix.bytesperline = static_cast<std::uint32_t>(probe.layout.bytes_per_line);
    pix.sizeimage = probe.size_image;
    pix.colorspace = V4L2_COLORSPACE_RAW;
    return *f;
  };
  auto fill_format = [&](v4l2_format& fmt) {
    fmt.fmt.pix.pixelformat = fourcc_of(d.layout.format);
    fmt.fmt.pix.width = static_cast<std::uint32_t>(d.layout.width);
    fmt.fmt.pix.height = static_cast<std::uint32_t>(d.layout.height);
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    fmt.fmt.pix.bytesperline = static_cast<std::uint32_t>(d.layout.bytes_per_line);
    fmt.fmt.pix.sizeimage = d.size_image;
    fmt.fmt.pix.colorspace = V4L2_COLORSPACE_RAW;
  };
  auto control_range = [&](std::uint32_t id, v4l2_queryctrl& q) {
    std::memset(&q, 0, sizeof q);
    q.id = id;
    switch (id) {
      case V4L2_CID_GAIN:
        q.type = V4L2_CTRL_TYPE_INTEGER;
        copy_name(q.name, sizeof q.name, "Gain");
        q.minimum = d.spec.gain_min, q.maximum = d.spec.gain_max, q.step = d.spec.gain_step;
        q.default_value = d.spec.gain_default;
        return true;
      case V4L2_CID_EXPOSURE_AUTO:
        q.type = V4L2_CTRL_TYPE_MENU;
        copy_name(q.name, sizeof q.name, "Auto Exposure");
        q.minimum = 0, q.maximum = 3, q.step = 1;
        q.default_value = d.spec.auto_exposure_default ? V4L2_EXPOSURE_APERTURE_PRIORITY : V4L2_EXPOSURE_MANUAL;
        return true;
      case V4L2_CID_EXPOSURE_ABSOLUTE:
        q.type = V4L2_CTRL_TYPE_INTEGER;
        copy_name(q.name, sizeof q.name, "Exposure Time, Absolute");
        q.minimum = d.spec.exposure_min, q.maximum = d.spec.exposure_max, q.step = d.spec.exposure_step;
        q.default_value = d.spec.exposure_default;
        if (d.auto_exposure) q.flags |= V4L2_CTRL_FLAG_INACTIVE;
        return true;
      default: return false;
    }
  };

  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto& cap = *static_cast<v4l2_capability*>(argument);
      std::memset(&cap, 0, sizeof cap);
      copy_name(cap.driver, sizeof cap.driver, d.spec.driver);
      copy_name(cap.card, sizeof cap.card, d.spec.card);
      copy_name(cap.bus_info, sizeof cap.bus_info, d.spec.bus_info);
      cap.version = 0x060100;
      cap.device_caps = V4L2_CAP_VIDEO_CAPTURE | (d.spec.streaming_io ? V4L2_CAP_STREAMING : V4L2_CAP_READWRITE);
      cap.capabilities = cap.device_caps | V4L2_CAP_DEVICE_CAPS;
      return 0;
    }
    case VIDIOC_ENUM_FMT: {
      auto& desc = *static_cast<v4l2_fmtdesc*>(argument);
      if (desc.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || desc.index >= d.spec.formats.size()) return fail(EINVAL);
      const EmulatedFormat& f = d.spec.formats[desc.index];
      const std::uint32_t index = desc.index;
      std::memset(&desc, 0, sizeof desc);
      desc.index = index;
      desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      desc.pixelformat = fourcc_of(f.format);
      desc.flags = f.format == PixelFormat::Mjpg ? V4L2_FMT_FLAG_COMPRESSED : 0;
      const std::string name = f.format == PixelFormat::Mjpg   ? "Motion-JPEG"
                               : f.format == PixelFormat::Yuyv ? "YUYV 4:2:2"
                                                               : std::string(to_string(f.format)) + " greyscale";
      copy_name(desc.description, sizeof desc.description, name);
      return 0;
    }
    case VIDIOC_ENUM_FRAMESIZES: {
      auto& size = *static_cast<v4l2_frmsizeenum*>(argument);
      const EmulatedFormat* f = find_format(size.pixel_format);
      if (f == nullptr || size.index >= f->sizes.size()) return fail(EINVAL);
      size.type = V4L2_FRMSIZE_TYPE_DISCRETE;
      size.discrete.width = static_cast<std::uint32_t>(f->sizes[size.index].first);
      size.discrete.height = static_cast<std::uint32_t>(f->sizes[size.index].second);
      return 0;
    }
    case VIDIOC_ENUM_FRAMEINTERVALS: {
      auto& interval = *static_cast<v4l2_frmivalenum*>(argument);
      const EmulatedFormat* f = find_format(interval.pixel_format);
      if (f == nullptr || interval.index >= f->rates_fps.size()) return fail(EINVAL);
      const bool size_offered = std::any_of(f->sizes.begin(), f->sizes.end(), [&](const auto& s) {
        return static_cast<std::uint32_t>(s.first) == interval.width && static_cast<std::uint32_t>(s.second) == interval.height;
      });
      if (!size_offered) return fail(EINVAL);
      interval.type = V4L2_FRMIVAL_TYPE_DISCRETE;  // UVC: 100 ns units
      interval.discrete.numerator = static_cast<std::uint32_t>(std::lround(1e7 / f->rates_fps[interval.index]));
      interval.discrete.denominator = 10000000;
      return 0;
    }
    case VIDIOC_G_FMT: {
      auto& fmt = *static_cast<v4l2_format*>(argument);
      if (fmt.type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      fill_format(fmt);
      return 0;
    }
    case VIDIOC_TRY_FMT:
    case VIDIOC_S_FMT: {
      auto& fmt = *static_cast<v4l2_format*>(argument);
      if (fmt.type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_FMT && (busy || d.streaming || !d.buffers.empty())) return fail(EBUSY);
      const EmulatedFormat& f = adjust(fmt.fmt.pix);
      if (request == VIDIOC_S_FMT) {
        d.set_layout(f.format, static_cast<int>(fmt.fmt.pix.width), static_cast<int>(fmt.fmt.pix.height));
        if (std::find(f.rates_fps.begin(), f.rates_fps.end(), d.fps) == f.rates_fps.end()) d.fps = f.rates_fps.front();
      }
      return 0;
    }
    case VIDIOC_G_PARM:
    case VIDIOC_S_PARM: {
      auto& parm = *static_cast<v4l2_streamparm*>(argument);
      if (parm.type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_PARM) {
        if (busy || d.streaming) return fail(EBUSY);
        const auto& tpf = parm.parm.capture.timeperframe;
        const double wanted = tpf.numerator == 0 ? d.fps : double(tpf.denominator) / tpf.numerator;
        const EmulatedFormat* f = find_format(fourcc_of(d.layout.format));
        if (f == nullptr) return fail(EINVAL);
        double best = f->rates_fps.front();
        for (const double r : f->rates_fps)
          if (std::abs(r - wanted) < std::abs(best - wanted)) best = r;
        d.fps = best;
      }
      std::memset(&parm.parm, 0, sizeof parm.parm);
      parm.parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
      parm.parm.capture.timeperframe.numerator = static_cast<std::uint32_t>(std::lround(1e7 / d.fps));
      parm.parm.capture.timeperframe.denominator = 10000000;
      parm.parm.capture.readbuffers = 0;
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto& req = *static_cast<v4l2_requestbuffers*>(argument);
      if (req.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || req.memory != V4L2_MEMORY_MMAP || !d.spec.streaming_io)
        return fail(EINVAL);
      if (busy || d.streaming) return fail(EBUSY);
      d.buffers.clear();
      d.queued.clear();
      d.done.clear();
      if (req.count == 0) {
        d.owner_fd = -1;
        return 0;
      }
      req.count = std::clamp<std::uint32_t>(req.count, 2, 32);
      d.buffers.resize(req.count);
      for (auto& b : d.buffers) b.memory = std::make_shared<std::vector<std::uint8_t>>(d.size_image);
      d.owner_fd = fd;
      return 0;
    }
    case VIDIOC_QUERYBUF:
    case VIDIOC_QBUF:
    case VIDIOC_DQBUF: {
      auto& buf = *static_cast<v4l2_buffer*>(argument);
      if (buf.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buf.memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
      if (!owner) return fail(d.owner_fd >= 0 ? EBUSY : EINVAL);
      auto describe = [&](int index) {
        const Device::Buffer& b = d.buffers[index];
        buf.index = static_cast<std::uint32_t>(index);
        buf.length = static_cast<std::uint32_t>(b.memory->size());
        buf.m.offset = static_cast<std::uint32_t>(index * kBufferOffsetUnit);
        buf.bytesused = b.done ? b.bytes_used : 0;
        buf.flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | (b.queued ? V4L2_BUF_FLAG_QUEUED : 0) |
                    (b.done ? V4L2_BUF_FLAG_DONE : 0);
        buf.field = V4L2_FIELD_NONE;
        buf.sequence = b.sequence;
        const double whole = std::floor(b.timestamp_s);
        buf.timestamp.tv_sec = static_cast<time_t>(whole);
        buf.timestamp.tv_usec = static_cast<suseconds_t>(std::lround((b.timestamp_s - whole) * 1e6));
      };
      if (request == VIDIOC_QUERYBUF) {
        if (buf.index >= d.buffers.size()) return fail(EINVAL);
        describe(static_cast<int>(buf.index));
        return 0;
      }
      if (request == VIDIOC_QBUF) {
        if (buf.index >= d.buffers.size() || d.buffers[buf.index].queued || d.buffers[buf.index].done) return fail(EINVAL);
        d.buffers[buf.index].queued = true;
        d.queued.push_back(static_cast<int>(buf.index));
        describe(static_cast<int>(buf.index));
        lock.unlock();
        changed_.notify_all();
        return 0;
      }
      if (!d.streaming) return fail(EINVAL);
      d.produce();
      while (d.done.empty()) {
        if (handle->nonblocking) return fail(EAGAIN);
        changed_.wait_for(lock, std::chrono::milliseconds(5));
        if (!d.plugged) return fail(ENODEV);
        if (!d.streaming) return fail(EINVAL);
        d.produce();
      }
      const int index = d.done.front();
      d.done.pop_front();
      describe(index);
      d.buffers[index].done = false;
      buf.flags &= ~static_cast<std::uint32_t>(V4L2_BUF_FLAG_DONE);
      d.count_delivery();
      return 0;
    }
    case VIDIOC_STREAMON:
    case VIDIOC_STREAMOFF: {
      if (*static_cast<int*>(argument) != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (!owner) return fail(busy ? EBUSY : EINVAL);
      if (request == VIDIOC_STREAMON) {
        if (!d.streaming) {
          d.streaming = true;
          d.stream_start = Clock::now();
          d.next_sequence = 0;
        }
      } else {
        d.stop_streaming();
      }
      lock.unlock();
      changed_.notify_all();
      return 0;
    }
    case VIDIOC_QUERYCTRL: {
      auto& q = *static_cast<v4l2_queryctrl*>(argument);
      if ((q.id & V4L2_CTRL_FLAG_NEXT_CTRL) != 0) {
        const std::uint32_t after = q.id & ~(V4L2_CTRL_FLAG_NEXT_CTRL | V4L2_CTRL_FLAG_NEXT_COMPOUND);
        for (const std::uint32_t id : kControlOrder)
          if (id > after) return control_range(id, q) ? 0 : fail(EINVAL);
        return fail(EINVAL);
      }
      return control_range(q.id, q) ? 0 : fail(EINVAL);
    }
    case VIDIOC_QUERYMENU: {
      auto& m = *static_cast<v4l2_querymenu*>(argument);
      if (m.id != V4L2_CID_EXPOSURE_AUTO) return fail(EINVAL);
      if (m.index == V4L2_EXPOSURE_MANUAL) copy_name(m.name, sizeof m.name, "Manual Mode");
      else if (m.index == V4L2_EXPOSURE_APERTURE_PRIORITY) copy_name(m.name, sizeof m.name, "Aperture Priority Mode");
      else return fail(EINVAL);
      return 0;
    }
    case VIDIOC_G_CTRL: {
      auto& c = *static_cast<v4l2_control*>(argument);
      switch (c.id) {
        case V4L2_CID_GAIN: c.value = d.gain; return 0;
        case V4L2_CID_EXPOSURE_ABSOLUTE: c.value = d.exposure; return 0;
        case V4L2_CID_EXPOSURE_AUTO: c.value = d.auto_exposure ? V4L2_EXPOSURE_APERTURE_PRIORITY : V4L2_EXPOSURE_MANUAL; return 0;
        default: return fail(EINVAL);
      }
    }
    case VIDIOC_S_CTRL: {
      // As the kernel's control framework: integers are clamped to the range and rounded to the
      // step, a menu index the menu does not have is EINVAL, a control under auto is EACCES.
      auto& c = *static_cast<v4l2_control*>(argument);
      auto settle = [](std::int32_t v, std::int32_t lo, std::int32_t hi, std::int32_t step) {
        const std::int64_t clamped = std::clamp<std::int64_t>(v, lo, hi);
        return static_cast<std::int32_t>(lo + (clamped - lo + step / 2) / step * step);
      };
      switch (c.id) {
        case V4L2_CID_GAIN: c.value = d.gain = settle(c.value, d.spec.gain_min, d.spec.gain_max, d.spec.gain_step); return 0;
        case V4L2_CID_EXPOSURE_ABSOLUTE:
          if (d.auto_exposure) return fail(EACCES);
          c.value = d.exposure = settle(c.value, d.spec.exposure_min, d.spec.exposure_max, d.spec.exposure_step);
          return 0;
        case V4L2_CID_EXPOSURE_AUTO:
          if (c.value != V4L2_EXPOSURE_MANUAL && c.value != V4L2_EXPOSURE_APERTURE_PRIORITY) return fail(EINVAL);
          d.auto_exposure = c.value == V4L2_EXPOSURE_APERTURE_PRIORITY;
          return 0;
        default: return fail(EINVAL);
      }
    }
    default: return fail(ENOTTY);
  }
}

int EmulatedUvc::poll(int fd, short events, short& revents, int timeout_ms) {
  std::unique_lock lock(mutex_);
  const auto deadline = Clock::now() + std::chrono::milliseconds(std::max(0, timeout_ms));
  for (;;) {
    const auto it = handles_.find(fd);
    if (it == handles_.end()) return fail(EBADF);
    const auto device = it->second->device;
    revents = 0;
    if (!device->plugged) {
      revents = POLLERR | POLLHUP;
      return 1;
    }
    if (!device->streaming && device->spec.streaming_io) {
      revents = POLLERR;  // as the kernel: polling a capture queue that is not streaming
      return 1;
    }
    if (!device->spec.streaming_io) {
      if (!device->hold && device->allowed != 0) revents = static_cast<short>(events & (POLLIN | POLLRDNORM));
    } else {
      device->produce();
      if (!device->done.empty()) revents = static_cast<short>(events & (POLLIN | POLLRDNORM));
    }
    if (revents != 0) return 1;
    const auto now = Clock::now();
    if (now >= deadline) return 0;
    auto wake = deadline;
    if (device->spec.paced && device->may_produce()) wake = std::min(wake, device->next_due());
    changed_.wait_until(lock, std::max(wake, now + std::chrono::microseconds(100)));
  }
}

std::ptrdiff_t EmulatedUvc::read(int fd, void* buffer, std::size_t size) {
  std::unique_lock lock(mutex_);
  const auto it = handles_.find(fd);
  if (it == handles_.end()) return fail(EBADF);
  const auto handle = it->second;
  Device& d = *handle->device;
  if (!d.plugged) return fail(ENODEV);
  if (d.spec.streaming_io) return fail(EINVAL);
  if (d.busy_elsewhere) return fail(EBUSY);
  while (d.hold || d.allowed == 0) {
    if (handle->nonblocking) return fail(EAGAIN);
    changed_.wait_for(lock, std::chrono::milliseconds(5));
    if (!d.plugged) return fail(ENODEV);
  }
  std::vector<std::uint8_t> frame(d.size_image);
  if (d.allowed > 0) --d.allowed;
  d.next_sequence = d.skip_dropped(d.next_sequence);
  const std::size_t used = d.draw(d.next_sequence++, frame);
  const std::size_t n = std::min(size, used);
  std::memcpy(buffer, frame.data(), n);
  d.count_delivery();
  return static_cast<std::ptrdiff_t>(n);
}

}  // namespace nirslam
