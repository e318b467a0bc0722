#pragma once

// Emulated cameras for the V4L2 tests: small frames (fast under AddressSanitizer), unpaced (a frame
// is ready whenever a buffer is queued), and a generator whose pixels encode the sequence number,
// so a test can tell which frame it got.

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "nirslam/capture/emulated_uvc.hpp"

namespace nirslam::testing {

// Every pixel of frame `sequence` holds (sequence * 3 + x) in the format's range.
inline std::size_t sequence_pattern(const EmulatedFrameRequest& request, std::span<std::uint8_t> buffer) {
  const BufferLayout& l = request.layout;
  const int bpp = bytes_per_pixel(l.format);
  const std::uint32_t max_value = (1u << bit_depth_of(l.format)) - 1u;
  for (int y = 0; y < l.height; ++y)
    for (int x = 0; x < l.width; ++x) {
      const std::uint32_t v = (request.sequence * 3u + static_cast<std::uint32_t>(x)) & max_value;
      std::uint8_t* p = buffer.data() + static_cast<std::size_t>(y) * l.bytes_per_line + static_cast<std::size_t>(x) * bpp;
      if (bpp == 1) {
        p[0] = static_cast<std::uint8_t>(v);
      } else if (l.format == PixelFormat::Yuyv) {
        p[0] = static_cast<std::uint8_t>(v);
        p[1] = 128;
      } else {
        p[0] = static_cast<std::uint8_t>(v & 0xFFu);
        p[1] = static_cast<std::uint8_t>(v >> 8);
      }
    }
  return static_cast<std::size_t>(l.bytes_per_line) * l.height;
}

// A small mono NIR camera at `node`: GREY, Y10, Y12, Y16 and YUYV at 64x48 and 32x24, 30/15 fps.
inline EmulatedCameraSpec small_camera(const std::string& node = "/dev/video0") {
  EmulatedCameraSpec spec;
  spec.node = node;
  spec.card = "Test NIR camera";
  spec.bus_info = "usb-test-1";
  for (const PixelFormat f : {PixelFormat::Grey, PixelFormat::Y10, PixelFormat::Y12, PixelFormat::Y16, PixelFormat::Yuyv})
    spec.formats.push_back({f, {{64, 48}, {32, 24}}, {30.0, 15.0}});
  spec.generator = sequence_pattern;
  return spec;
}

inline std::shared_ptr<EmulatedUvc> emulator_with(const EmulatedCameraSpec& spec) {
  auto emulator = std::make_shared<EmulatedUvc>();
  emulator->add_camera(spec);
  return emulator;
}

}  // namespace nirslam::testing
