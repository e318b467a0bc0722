#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <set>
#include <sstream>

#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

constexpr std::string_view kReal = "v4l2:";
constexpr std::string_view kEmulated = "v4l2-emulated:";

double number(const std::string& text, const std::string& source, const std::string& key, double lo, double hi) {
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc() || ptr != end || !std::isfinite(value))
    throw InputError(source, key, "'" + text + "' is not a number");
  if (value < lo || value > hi) {
    std::ostringstream range;
    range << "'" << text << "' is outside " << lo << ".." << hi;
    throw InputError(source, key, range.str());
  }
  return value;
}

int integer(const std::string& text, const std::string& source, const std::string& key, int lo, int hi) {
  const double value = number(text, source, key, lo, hi);
  if (value != std::floor(value)) throw InputError(source, key, "'" + text + "' is not a whole number");
  return static_cast<int>(value);
}

bool on_off(const std::string& text, const std::string& source, const std::string& key) {
  if (text == "on" || text == "1" || text == "true" || text == "yes") return true;
  if (text == "off" || text == "0" || text == "false" || text == "no") return false;
  throw InputError(source, key, "'" + text + "' is not on or off");
}

std::string format_number(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

}  // namespace

bool is_v4l2_source_string(std::string_view text) {
  return text.substr(0, kReal.size()) == kReal || text.substr(0, kEmulated.size()) == kEmulated;
}

V4l2SourceSpec parse_v4l2_source_spec(std::string_view text) {
  const std::string source(text);
  V4l2SourceSpec spec;
  std::string_view rest;
  if (text.substr(0, kEmulated.size()) == kEmulated) {
    spec.emulated = true;
    rest = text.substr(kEmulated.size());
  } else if (text.substr(0, kReal.size()) == kReal) {
    rest = text.substr(kReal.size());
  } else {
    throw InputError(source, "source", "a V4L2 source starts with v4l2: or v4l2-emulated:");
  }
  const std::size_t query = rest.find('?');
  const std::string device(rest.substr(0, query));
  if (!device.empty()) spec.device = device;
  if (spec.device.rfind("/dev/", 0) != 0) throw InputError(source, "device", "'" + spec.device + "' is not a /dev/ node");

  std::set<std::string> seen;
  if (query != std::string_view::npos) {
    std::string_view params = rest.substr(query + 1);
    while (!params.empty()) {
      const std::size_t amp = params.find('&');
      const std::string_view pair = params.substr(0, amp);
      params = amp == std::string_view::npos ? std::string_view() : params.substr(amp + 1);
      if (pair.empty()) continue;
      const std::size_t eq = pair.find('=');
      if (eq == std::string_view::npos) throw InputError(source, std::string(pair), "expected key=value");
      const std::string key(pair.substr(0, eq));
      const std::string value(pair.substr(eq + 1));
      if (!seen.insert(key).second) throw InputError(source, key, "given twice");
      if (key == "format") {
        spec.format = pixel_format_from_name(value);
        if (!spec.format) throw InputError(source, key, "'" + value + "' is not one of GREY, Y10, Y12, Y16, YUYV, MJPG");
      } else if (key == "size") {
        const std::size_t x = value.find('x');
        if (x == std::string::npos) throw InputError(source, key, "'" + value + "' is not WIDTHxHEIGHT");
        spec.width = integer(value.substr(0, x), source, key, 1, 16384);
        spec.height = integer(value.substr(x + 1), source, key, 1, 16384);
      } else if (key == "fps") {
        spec.fps = number(value, source, key, 0.1, 1000.0);
      } else if (key == "buffers") {
        spec.buffer_count = integer(value, source, key, 2, 32);
      } else if (key == "queue") {
        spec.queue_capacity = integer(value, source, key, 1, 64);
      } else if (key == "stereo") {
        if (value != "sbs" && value != "none") throw InputError(source, key, "'" + value + "' is not sbs or none");
        spec.stereo_side_by_side = value == "sbs";
      } else if (key == "exposure_ms") {
        spec.exposure_ms = number(value, source, key, 0.0, 10000.0);
      } else if (key == "gain") {
        spec.gain = number(value, source, key, -1e6, 1e6);
      } else if (key == "auto_exposure") {
        spec.auto_exposure = on_off(value, source, key);
      } else if (key == "lock") {
        spec.locked = on_off(value, source, key);
      } else if (key == "reconnect_s") {
        spec.reconnect_wait_s = number(value, source, key, 0.0, 3600.0);
      } else if (key == "stall_s") {
        spec.stall_timeout_s = number(value, source, key, 0.01, 3600.0);
      } else if (key == "gain_unity") {
        spec.gain_unity = number(value, source, key, 1e-6, 1e6);
      } else if (key == "frames" && spec.emulated) {
        spec.emulated_frames = integer(value, source, key, 0, 100000000);
      } else if (key == "paced" && spec.emulated) {
        spec.emulated_paced = on_off(value, source, key);
      } else {
        throw InputError(source, key, "unknown key (format, size, fps, buffers, queue, stereo, exposure_ms, gain, "
                                      "auto_exposure, lock, reconnect_s, stall_s, gain_unity" +
                                          std::string(spec.emulated ? ", frames, paced)" : ")"));
      }
    }
  }
  // The emulated stereo camera is side by side unless the string says otherwise.
  if (spec.emulated && spec.device == "/dev/video2" && seen.count("stereo") == 0) spec.stereo_side_by_side = true;
  if (spec.exposure_ms && spec.auto_exposure.value_or(false))
    throw InputError(source, "exposure_ms", "an exposure was given with auto_exposure=on");
  return spec;
}

std::string V4l2SourceSpec::to_string() const {
  std::string text = std::string(emulated ? kEmulated : kReal) + device;
  std::vector<std::string> params;
  if (format) params.push_back("format=" + std::string(nirslam::to_string(*format)));
  if (width > 0 && height > 0) params.push_back("size=" + std::to_string(width) + "x" + std::to_string(height));
  if (fps > 0.0) params.push_back("fps=" + format_number(fps));
  if (buffer_count != 4) params.push_back("buffers=" + std::to_string(buffer_count));
  if (queue_capacity != 4) params.push_back("queue=" + std::to_string(queue_capacity));
  if (stereo_side_by_side) params.push_back("stereo=sbs");
  else if (emulated && device == "/dev/video2") params.push_back("stereo=none");
  if (exposure_ms) params.push_back("exposure_ms=" + format_number(*exposure_ms));
  if (gain) params.push_back("gain=" + format_number(*gain));
  if (auto_exposure) params.push_back(std::string("auto_exposure=") + (*auto_exposure ? "on" : "off"));
  if (locked) params.push_back("lock=on");
  if (reconnect_wait_s != 3.0) params.push_back("reconnect_s=" + format_number(reconnect_wait_s));
  if (stall_timeout_s != 5.0) params.push_back("stall_s=" + format_number(stall_timeout_s));
  if (gain_unity > 0.0) params.push_back("gain_unity=" + format_number(gain_unity));
  if (emulated && emulated_frames > 0) params.push_back("frames=" + std::to_string(emulated_frames));
  if (emulated && !emulated_paced) params.push_back("paced=off");
  for (std::size_t i = 0; i < params.size(); ++i) text += (i == 0 ? "?" : "&") + params[i];
  return text;
}

const char* to_string(CameraConnection connection) {
  switch (connection) {
    case CameraConnection::Opening: return "opening";
    case CameraConnection::Streaming: return "streaming";
    case CameraConnection::Unplugged: return "unplugged";
    case CameraConnection::Reconnecting: return "reconnecting";
    case CameraConnection::Stopped: return "stopped";
    case CameraConnection::Failed: return "failed";
  }
  return "?";
}

}  // namespace nirslam
