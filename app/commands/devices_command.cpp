#include <linux/videodev2.h>

#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "commands/subcommand.hpp"
#include "nirslam/capture/device_info.hpp"
#include "nirslam/capture/emulated_uvc.hpp"
#include "nirslam/capture/v4l2_io.hpp"
#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam::app {
namespace {

struct DevicesOptions {
  bool emulated = false;
  std::string device;    // only this node
  int capture_frames = 0;  // stream this many frames from the device as a check
};

std::string rates_text(const std::vector<double>& rates) {
  std::string text;
  for (const double r : rates) text += (text.empty() ? "" : ", ") + fmt::format("{:g}", r);
  return text.empty() ? "rate not listed" : text + " fps";
}

std::string control_text(const ControlInfo& c) {
  std::string text = fmt::format("{:<26} ", c.name);
  if (c.is_menu) text += fmt::format("menu {}..{}", c.minimum, c.maximum);
  else if (c.is_boolean) text += "on/off";
  else text += fmt::format("{}..{} step {}", c.minimum, c.maximum, c.step);
  text += fmt::format(", default {}, now {}", c.default_value, c.value);
  if (c.id == V4L2_CID_EXPOSURE_ABSOLUTE)
    text += fmt::format("  (100 us units: {:g}..{:g} ms, now {:g} ms)", c.minimum * 0.1, c.maximum * 0.1, c.value * 0.1);
  if (c.id == V4L2_CID_EXPOSURE_AUTO) text += c.value == V4L2_EXPOSURE_MANUAL ? "  (manual)" : "  (auto)";
  return text;
}

void print_device(const DeviceInfo& d, bool emulated) {
  if (!d.error.empty()) {
    std::printf("%s  unavailable: %s\n\n", d.node.c_str(), d.error.c_str());
    return;
  }
  std::printf("%s  %s  (%s, %s)\n", d.node.c_str(), d.card.c_str(), d.driver.c_str(), d.bus_info.c_str());
  std::printf("  source: %s%s\n", emulated ? "v4l2-emulated:" : "v4l2:", d.node.c_str());
  std::printf("  I/O: %s\n", d.can_stream ? "memory-mapped streaming" : (d.can_read ? "read() only" : "none nirslam can use"));
  std::printf("  formats:\n");
  for (const FormatInfo& f : d.formats) {
    std::printf("    %-5s %s%s\n", f.name.c_str(), f.description.c_str(), f.supported ? "" : "  (not convertible)");
    for (const FrameSizeInfo& s : f.sizes)
      std::printf("          %s @ %s\n", fmt::format("{}x{}", s.width, s.height).c_str(), rates_text(s.rates_fps).c_str());
  }
  std::printf("  controls:\n");
  if (d.controls.empty()) std::printf("    none\n");
  for (const ControlInfo& c : d.controls) std::printf("    %s\n", control_text(c).c_str());
  std::printf("\n");
}

// Streams a few frames as a check that the device works end to end: rate, drops, exposure.
int capture_check(const DevicesOptions& options) {
  V4l2SourceSpec spec;
  spec.device = options.device.empty() ? "/dev/video0" : options.device;
  spec.emulated = options.emulated;
  spec.stereo_side_by_side = options.emulated && spec.device == "/dev/video2";
  spec.queue_capacity = 8;
  const auto source = open_v4l2_source(spec);
  std::printf("capturing %d frames from %s\n", options.capture_frames, source->info().description.c_str());
  std::printf("%6s %14s %10s %8s %9s %7s\n", "frame", "timestamp[s]", "exposure", "gain", "mean", "size");
  int frames = 0;
  while (frames < options.capture_frames) {
    const auto frame = source->next();
    if (!frame) break;
    const double scale = frame->bit_depth > 8 ? 1.0 / (1 << (frame->bit_depth - 8)) : 1.0;
    std::printf("%6lld %14.6f %7.2f ms %8.3f %9.1f %3dx%d\n", static_cast<long long>(frame->index), frame->timestamp_s,
                frame->exposure_ms.value_or(0.0), frame->gain.value_or(0.0), cv::mean(frame->image)[0] * scale,
                frame->width(), frame->height());
    ++frames;
  }
  const CameraState state = source->controls()->state();
  std::printf("%d frames, %.1f fps measured, %lld dropped by the driver, %lld by the queue\n", frames, state.measured_fps,
              static_cast<long long>(state.frames_dropped_by_driver), static_cast<long long>(state.frames_dropped_by_queue));
  if (!state.message.empty()) std::printf("%s\n", state.message.c_str());
  return frames == options.capture_frames ? 0 : 1;
}

int run_devices(const DevicesOptions& options) {
  try {
    const std::shared_ptr<V4l2Io> io =
        options.emulated ? std::shared_ptr<V4l2Io>(make_emulated_nir_cameras()) : make_system_v4l2_io();
    if (options.capture_frames > 0) return capture_check(options);
    std::vector<DeviceInfo> devices;
    if (!options.device.empty()) devices.push_back(describe_device(*io, options.device));
    else devices = enumerate_devices(*io);
    if (devices.empty()) {
      std::printf("No video capture devices (/dev/video*). 'nirslam devices --emulated' shows the emulated cameras.\n");
      return 0;
    }
    if (options.emulated) std::printf("Emulated UVC driver (no real device is opened):\n\n");
    for (const DeviceInfo& d : devices) print_device(d, options.emulated);
    std::printf("Open one with a source string, e.g. %s%s?format=Y16&size=640x480&fps=30\n",
                options.emulated ? "v4l2-emulated:" : "v4l2:", devices.front().node.c_str());
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}

}  // namespace

void add_devices_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<DevicesOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "devices",
      "List the V4L2 cameras (/dev/video*): name, bus, pixel formats with their frame sizes and rates, and the\n"
      "controls (exposure in 100 us units, gain, auto exposure) with their ranges. --emulated lists the emulated\n"
      "driver's cameras instead (a mono NIR camera and a side-by-side stereo one), so it works without a camera.");
  cmd->add_flag("--emulated", options->emulated, "Use the emulated UVC driver instead of the kernel's devices");
  cmd->add_option("--device", options->device, "Only this node, e.g. /dev/video0");
  cmd->add_option("--capture", options->capture_frames,
                  "Stream this many frames from --device (default /dev/video0) and print their timestamps, exposure, "
                  "gain and the drops")
      ->check(CLI::Range(1, 100000));
  cmd->callback([options, &action] { action = [options] { return run_devices(*options); }; });
}

}  // namespace nirslam::app
