#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "nirslam/capture/pixel_format.hpp"
#include "nirslam/capture/v4l2_io.hpp"

namespace nirslam {

// A format an emulated camera offers: its sizes, and the rates offered at every size.
struct EmulatedFormat {
  PixelFormat format = PixelFormat::Grey;
  std::vector<std::pair<int, int>> sizes;  // width, height
  std::vector<double> rates_fps;
};

// What the generator is asked to draw: frame `sequence` at exposure and gain in device units.
struct EmulatedFrameRequest {
  std::uint32_t sequence = 0;
  double timestamp_s = 0.0;
  BufferLayout layout;
  std::int32_t exposure_100us = 0;
  std::int32_t gain = 0;
};

// Fills the buffer (exactly the bytes a frame of `request.layout` takes; for MJPG, at most the
// buffer's size) and returns the bytes used.
using EmulatedFrameGenerator = std::function<std::size_t(const EmulatedFrameRequest& request, std::span<std::uint8_t> buffer)>;

struct EmulatedCameraSpec {
  std::string node = "/dev/video0";
  std::string card = "Emulated NIR camera";
  std::string driver = "uvcvideo";
  std::string bus_info = "usb-0000:00:14.0-1";
  std::vector<EmulatedFormat> formats;
  bool streaming_io = true;  // false: only read() (V4L2_CAP_READWRITE), as some small drivers
  bool side_by_side = false; // the pattern draws two views side by side (a stereo camera)
  // Controls, as a UVC camera reports them. Exposure in 100 us units, as V4L2 defines it.
  std::int32_t exposure_min = 1, exposure_max = 5000, exposure_step = 1, exposure_default = 100;
  std::int32_t gain_min = 0, gain_max = 255, gain_step = 1, gain_default = 16;
  bool auto_exposure_default = false;
  // Paced: frame k is ready at STREAMON + k / fps of real time, and frames for which no buffer
  // was queued are dropped as a UVC driver does (a sequence gap). Unpaced: a frame is ready
  // whenever a buffer is queued, which makes tests fast and deterministic.
  bool paced = false;
  double first_timestamp_s = 1000.0;  // kernel timestamp of sequence 0
  EmulatedFrameGenerator generator;   // empty: a moving textured pattern lit by the exposure and gain
};

// An emulated UVC driver behind the V4L2 seam, for tests and the `--emulated` demo: device nodes,
// QUERYCAP, ENUM_FMT / ENUM_FRAMESIZES / ENUM_FRAMEINTERVALS, S_FMT / G_FMT / TRY_FMT,
// S_PARM / G_PARM, REQBUFS / QUERYBUF / QBUF / DQBUF on buffers handed out by mmap, STREAMON /
// STREAMOFF, QUERYCTRL / G_CTRL / S_CTRL (exposure_absolute, auto exposure, gain), poll and
// read. It fails as the kernel does: EAGAIN when no frame is ready on a non-blocking descriptor,
// EBUSY when another descriptor (or another program, scripted) owns the stream, EACCES for a
// manual exposure under auto exposure, ENOTTY for unknown requests, and ENODEV on every call
// after a scripted unplug; open() of an unplugged node fails with ENOENT. Like the kernel's
// control framework it clamps an integer control to its range and rounds it to its step (so the
// range check that names the control is nirslam's, above the seam). Thread-safe.
class EmulatedUvc final : public V4l2Io {
public:
  EmulatedUvc();
  ~EmulatedUvc() override;

  void add_camera(EmulatedCameraSpec spec);

  // Scripts. Sequences in `dropped` are skipped by the "driver" (the sequence counter jumps).
  void drop_sequences(const std::string& node, std::set<std::uint32_t> dropped);
  // The device disappears after it has delivered `frames` more frames (0: now).
  void unplug_after(const std::string& node, int frames);
  void unplug(const std::string& node) { unplug_after(node, 0); }
  // A new device instance at the node; the frame allowance and hold carry over.
  void replug(const std::string& node);
  // Another program holds the stream: S_FMT and REQBUFS fail with EBUSY.
  void set_busy_elsewhere(const std::string& node, bool busy);
  // While held, no frame becomes ready (DQBUF: EAGAIN; poll times out).
  void hold_frames(const std::string& node, bool hold);

  // Only `frames` more frames become ready (then EAGAIN, as when holding), so a test decides how
  // many frames exist; negative: no limit (the default). Adds to what is still allowed.
  void allow_frames(const std::string& node, int frames);
  void limit_frames(const std::string& node, int frames);  // sets the allowance instead

  // What the device did, for tests: frames delivered, and the exposure (100 us units) and gain
  // each delivered sequence was taken with.
  int frames_delivered(const std::string& node) const;
  std::map<std::uint32_t, std::pair<std::int32_t, std::int32_t>> exposures_used(const std::string& node) const;
  bool plugged(const std::string& node) const;

  std::vector<std::string> device_nodes() override;
  int open(const std::string& path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* argument) override;
  void* mmap(std::size_t length, int protection, int flags, int fd, std::int64_t offset) override;
  int munmap(void* address, std::size_t length) override;
  int poll(int fd, short events, short& revents, int timeout_ms) override;
  std::ptrdiff_t read(int fd, void* buffer, std::size_t size) override;

  struct Device;
  struct Handle;

private:
  std::shared_ptr<Device> device_of(const std::string& node) const;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::string, std::shared_ptr<Device>> devices_;
  std::map<int, std::shared_ptr<Handle>> handles_;
  int next_fd_ = 100;
};

// The cameras `nirslam devices --emulated` and "v4l2-emulated:" sources show: a mono NIR camera
// (GREY, Y10, Y12, Y16, YUYV, MJPG at 640x480 and 320x240) and a side-by-side stereo one (GREY
// and Y16 at 1280x480, both views in one frame).
EmulatedCameraSpec emulated_mono_nir_camera(const std::string& node = "/dev/video0");
EmulatedCameraSpec emulated_stereo_nir_camera(const std::string& node = "/dev/video2");
// A driver with both: the mono camera at /dev/video0 and the stereo one at /dev/video2, frames at
// the device rate in real time (`paced`) or on demand.
std::shared_ptr<EmulatedUvc> make_emulated_nir_cameras(bool paced = true);

// The default pattern: a textured wall drifting across the view, brightness proportional to
// exposure x gain, the right view of a stereo frame shifted by a disparity. Any layout.
std::size_t draw_emulated_pattern(const EmulatedFrameRequest& request, bool side_by_side, std::span<std::uint8_t> buffer);

}  // namespace nirslam
