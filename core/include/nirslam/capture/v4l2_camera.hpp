#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/capture/device_info.hpp"
#include "nirslam/capture/pixel_format.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {

class V4l2Io;

// The device went away (ENODEV/EIO: unplugged) while it was open. What was captured before stays valid.
class DeviceGoneError : public InputError {
public:
  using InputError::InputError;
};

// What the caller asks for; fields left empty take the device's first (or current) choice.
struct StreamRequest {
  std::optional<PixelFormat> format;
  int width = 0;   // 0: the device's first size for the format (or its current size)
  int height = 0;
  double fps = 0.0;  // 0: leave the device's rate
  int buffer_count = 4;  // memory-mapped buffers requested from the driver
};

// What the driver agreed to.
struct NegotiatedFormat {
  BufferLayout layout;
  std::uint32_t size_image = 0;  // bytes a buffer holds
  double fps = 0.0;              // from G_PARM, 0 when the device does not say
  int buffer_count = 0;          // what REQBUFS granted
  bool uses_read = false;        // no streaming I/O: frames come through read()
};

// One frame taken off the driver's queue, converted.
struct CapturedImage {
  cv::Mat image;            // CV_8UC1 or CV_16UC1, the whole frame (both halves of a stereo one)
  int bit_depth = 8;
  std::uint32_t sequence = 0;  // the driver's frame counter: a gap is a frame the driver dropped
  double timestamp_s = 0.0;    // the kernel's timestamp (CLOCK_MONOTONIC), seconds
};

// One open V4L2 capture device: negotiation, controls and memory-mapped streaming, through the
// seam. Not thread-safe: one thread (the capture thread) owns it. Errors are nirslam::InputError
// naming the device node and the field (format, size, control); DeviceGoneError after an unplug.
class V4l2Camera {
public:
  V4l2Camera(std::shared_ptr<V4l2Io> io, std::string node);
  ~V4l2Camera();
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  const std::string& node() const { return node_; }
  const DeviceInfo& info() const { return info_; }

  // S_FMT / S_PARM / REQBUFS / QUERYBUF / mmap / QBUF. A format the device does not offer or
  // nirslam cannot convert, or a size it does not list, is an InputError naming the field and
  // what the device offers; a device another program streams from is "busy" (EBUSY).
  NegotiatedFormat configure(const StreamRequest& request);
  const NegotiatedFormat& format() const { return format_; }

  void start();  // STREAMON
  void stop();   // STREAMOFF, buffers unmapped and released
  bool streaming() const { return streaming_; }

  // Waits up to `timeout_ms` for a frame: std::nullopt when none came (EAGAIN, poll timeout).
  // The buffer goes back to the driver's queue after conversion.
  std::optional<CapturedImage> capture(int timeout_ms);

  // Controls, in device units. set_control checks the range against QUERYCTRL and throws an
  // InputError naming the control when the value is outside it; returns the value the driver
  // kept (read back, as drivers round to their step).
  std::optional<ControlInfo> control(std::uint32_t id);
  std::int32_t get_control(std::uint32_t id);
  std::int32_t set_control(std::uint32_t id, std::int32_t value);
  // S_PARM time per frame; returns the rate the driver chose.
  double set_frame_rate(double fps);

private:
  int xioctl(unsigned long request, void* argument, const char* what);
  [[noreturn]] void fail(const std::string& field, const std::string& message, int error_number);
  void release_buffers();

  struct MappedBuffer {
    void* start = nullptr;
    std::size_t length = 0;
  };

  std::shared_ptr<V4l2Io> io_;
  std::string node_;
  int fd_ = -1;
  DeviceInfo info_;
  NegotiatedFormat format_;
  std::vector<MappedBuffer> buffers_;
  std::vector<std::uint8_t> read_buffer_;
  bool streaming_ = false;
  std::string gone_message_;  // set when the device vanished after the last frame was taken
};

}  // namespace nirslam
