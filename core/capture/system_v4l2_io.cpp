#include <fcntl.h>
#include <libv4l2.h>
#include <poll.h>
#include <sys/mman.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <system_error>

#include "nirslam/capture/v4l2_io.hpp"

namespace nirslam {
namespace {

// "video10" after "video2": the number, not the text, orders the nodes.
bool natural_less(const std::string& a, const std::string& b) {
  auto split = [](const std::string& s) {
    std::size_t digits = s.size();
    while (digits > 0 && std::isdigit(static_cast<unsigned char>(s[digits - 1])) != 0) --digits;
    const long number = digits < s.size() ? std::stol(s.substr(digits)) : -1;
    return std::make_pair(s.substr(0, digits), number);
  };
  return split(a) < split(b);
}

class SystemV4l2Io final : public V4l2Io {
public:
  std::vector<std::string> device_nodes() override {
    std::vector<std::string> nodes;
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind("video", 0) == 0 && name.size() > 5) nodes.push_back(entry.path().string());
    }
    std::sort(nodes.begin(), nodes.end(), natural_less);
    return nodes;
  }
  int open(const std::string& path, int flags) override { return v4l2_open(path.c_str(), flags); }
  int close(int fd) override { return v4l2_close(fd); }
  int ioctl(int fd, unsigned long request, void* argument) override { return v4l2_ioctl(fd, request, argument); }
  void* mmap(std::size_t length, int protection, int flags, int fd, std::int64_t offset) override {
    return v4l2_mmap(nullptr, length, protection, flags, fd, offset);
  }
  int munmap(void* address, std::size_t length) override { return v4l2_munmap(address, length); }
  int poll(int fd, short events, short& revents, int timeout_ms) override {
    pollfd p{fd, events, 0};
    const int result = ::poll(&p, 1, timeout_ms);
    revents = p.revents;
    return result;
  }
  std::ptrdiff_t read(int fd, void* buffer, std::size_t size) override { return v4l2_read(fd, buffer, size); }
};

}  // namespace

std::shared_ptr<V4l2Io> make_system_v4l2_io() { return std::make_shared<SystemV4l2Io>(); }

}  // namespace nirslam
