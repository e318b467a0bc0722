#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace nirslam {

// The seam under the V4L2 system calls. Everything above it (enumeration, negotiation, streaming,
// controls, the V4L2 source) is the same code for a real camera and for the emulated driver the
// tests use, because both are reached only through this interface. The calls keep the system
// call conventions: -1 (or MAP_FAILED) with errno set on failure, so the error handling above the
// seam is exercised by the emulator exactly as by the kernel.
class V4l2Io {
public:
  virtual ~V4l2Io() = default;
  V4l2Io() = default;
  V4l2Io(const V4l2Io&) = delete;
  V4l2Io& operator=(const V4l2Io&) = delete;

  // The video device nodes present now (/dev/video*), in natural order (video2 before video10).
  virtual std::vector<std::string> device_nodes() = 0;

  virtual int open(const std::string& path, int flags) = 0;
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* argument) = 0;
  virtual void* mmap(std::size_t length, int protection, int flags, int fd, std::int64_t offset) = 0;
  virtual int munmap(void* address, std::size_t length) = 0;
  // Like poll(2) on one descriptor: > 0 with `revents` set when ready, 0 on timeout, -1 on error.
  virtual int poll(int fd, short events, short& revents, int timeout_ms) = 0;
  virtual std::ptrdiff_t read(int fd, void* buffer, std::size_t size) = 0;
};

// The real seam: libv4l2 (v4l2_open, v4l2_ioctl, v4l2_mmap, ...) on the kernel's device nodes.
std::shared_ptr<V4l2Io> make_system_v4l2_io();

}  // namespace nirslam
