#include "nirslam/capture/v4l2_source.hpp"

#include <linux/videodev2.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <sstream>
#include <thread>

#include <spdlog/spdlog.h>

#include "nirslam/capture/control_hub.hpp"
#include "nirslam/capture/emulated_uvc.hpp"
#include "nirslam/capture/v4l2_camera.hpp"
#include "nirslam/capture/v4l2_io.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

using Clock = std::chrono::steady_clock;

constexpr double kExposureUnitMs = 0.1;  // V4L2_CID_EXPOSURE_ABSOLUTE counts 100 us
constexpr int kCaptureWaitMs = 50;       // poll timeout: how soon the capture thread sees a stop or a control

ControlRange range_of(const std::optional<ControlInfo>& control, double scale) {
  ControlRange r;
  if (!control) return r;
  r.available = true;
  r.minimum = control->minimum * scale;
  r.maximum = control->maximum * scale;
  r.step = control->step * scale;
  r.default_value = control->default_value * scale;
  return r;
}

struct QueuedFrame {
  Frame frame;
  cv::Mat right;
};

class V4l2SourceImpl final : public V4l2Source {
public:
  V4l2SourceImpl(const V4l2SourceSpec& spec, std::shared_ptr<V4l2Io> io)
      : spec_(spec), io_(std::move(io)), hub_(std::make_shared<CameraControlHub>(spec.device)) {
    if (spec_.queue_capacity < 1) throw InputError(spec_.device, "queue", "the frame queue needs room for one frame");
    open_and_start();
    describe();
    thread_ = std::thread([this] { capture_loop(); });
  }

  ~V4l2SourceImpl() override { stop_thread(); }

  const SourceInfo& info() const override { return info_; }

  std::optional<Frame> next() override {
    std::unique_lock lock(mutex_);
    const auto stalled_at = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(spec_.stall_timeout_s));
    for (;;) {
      if (!queue_.empty()) {
        QueuedFrame q = std::move(queue_.front());
        queue_.pop_front();
        last_right_ = q.right.empty() ? std::nullopt : std::optional<cv::Mat>(q.right);
        return std::move(q.frame);
      }
      if (!failure_.empty()) {
        const std::string message = std::move(failure_);
        failure_.clear();
        ended_ = true;
        throw InputError(spec_.device, "stream", message);
      }
      if (ended_) return std::nullopt;
      if (unplugged_at_) {
        const auto give_up = *unplugged_at_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(spec_.reconnect_wait_s));
        if (Clock::now() >= give_up) {
          // The stream ends here; what was captured before the unplug has been delivered.
          ended_ = true;
          hub_->update([&](CameraState& s) {
            s.message = "stream ended: " + spec_.device + " was unplugged after " + std::to_string(s.frames_captured) +
                        " frames; plug it back in and press Start to resume";
            end_reason_ = s.message;
          });
          return std::nullopt;
        }
        frame_ready_.wait_until(lock, give_up);
        continue;
      }
      if (Clock::now() >= stalled_at) {
        std::ostringstream message;
        message << "no frame for " << spec_.stall_timeout_s << " s: the camera stalled";
        hub_->update([&](CameraState& s) { s.error = message.str(); });
        throw InputError(spec_.device, "stream", message.str());
      }
      frame_ready_.wait_until(lock, std::min(stalled_at, Clock::now() + std::chrono::milliseconds(200)));
    }
  }

  void rewind() override {
    stop_thread();
    {
      const std::lock_guard lock(mutex_);
      queue_.clear();
      ended_ = false;
      end_reason_.clear();
      failure_.clear();
      unplugged_at_.reset();
    }
    last_right_.reset();
    camera_.reset();
    hub_->update([](CameraState& s) {
      s.connection = CameraConnection::Opening;
      s.error.clear();
    });
    try {
      open_and_start();
    } catch (const InputError&) {
      const std::lock_guard lock(mutex_);
      ended_ = true;  // next() ends at once instead of waiting for a thread that is not there
      throw;
    }
    describe();
    stop_requested_ = false;
    thread_ = std::thread([this] { capture_loop(); });
  }

  std::string end_reason() const override {
    const std::lock_guard lock(mutex_);
    return end_reason_;
  }

  std::int64_t frames_dropped() const override {
    const CameraState s = hub_->state();
    return s.frames_dropped_by_driver + s.frames_dropped_by_queue;
  }

  std::shared_ptr<CameraControls> controls() const override { return hub_; }
  std::optional<cv::Mat> last_right_image() const override { return last_right_; }

private:
  // Opens, negotiates, applies the source string's controls and starts streaming. Throws
  // InputError naming the device and the field; the state shows the error too.
  void open_and_start() {
    try {
      camera_ = std::make_unique<V4l2Camera>(io_, spec_.device);
      StreamRequest request{spec_.format, spec_.width, spec_.height, spec_.fps, spec_.buffer_count};
      const NegotiatedFormat negotiated = camera_->configure(request);
      if (spec_.stereo_side_by_side && negotiated.layout.width % 2 != 0)
        throw InputError(spec_.device, "stereo", "side-by-side frames need an even width, got " + std::to_string(negotiated.layout.width));
      read_control_ranges();
      apply_initial_controls();
      camera_->start();
      last_sequence_.reset();
      hub_->update([&](CameraState& s) {
        s.connection = CameraConnection::Streaming;
        s.error.clear();
      });
    } catch (const InputError& e) {
      camera_.reset();
      hub_->update([&](CameraState& s) {
        s.connection = CameraConnection::Failed;
        s.error = e.what();
      });
      throw;
    }
  }

  void read_control_ranges() {
    exposure_control_ = camera_->control(V4L2_CID_EXPOSURE_ABSOLUTE);
    gain_control_ = camera_->control(V4L2_CID_GAIN);
    auto_control_ = camera_->control(V4L2_CID_EXPOSURE_AUTO);
    gain_unity_ = spec_.gain_unity > 0.0 ? spec_.gain_unity
                  : (gain_control_ && gain_control_->default_value > 0) ? gain_control_->default_value
                                                                         : 1.0;
    const NegotiatedFormat& f = camera_->format();
    ControlRange fps_range;
    std::vector<double> rates;
    for (const FormatInfo& format : camera_->info().formats) {
      if (format.fourcc != fourcc_of(f.layout.format)) continue;
      for (const FrameSizeInfo& size : format.sizes) {
        if (size.width != f.layout.width || size.height != f.layout.height || size.rates_fps.empty()) continue;
        fps_range.available = true;
        fps_range.minimum = size.rates_fps.back();
        fps_range.maximum = size.rates_fps.front();
        fps_range.default_value = f.fps;
        rates = size.rates_fps;
      }
    }
    hub_->update([&](CameraState& s) {
      s.card = camera_->info().card;
      s.width = f.layout.width;
      s.height = f.layout.height;
      s.bit_depth = bit_depth_of(f.layout.format);
      s.format = std::string(to_string(f.layout.format)) + " " + std::to_string(f.layout.width) + "x" + std::to_string(f.layout.height);
      s.stereo_side_by_side = spec_.stereo_side_by_side;
      s.fps = f.fps;
      s.buffer_count = f.buffer_count;
      s.exposure_ms = range_of(exposure_control_, kExposureUnitMs);
      s.gain = range_of(gain_control_, 1.0);
      s.fps_range = fps_range;
      s.rates_fps = rates;
      s.auto_exposure_available = auto_control_.has_value();
      s.auto_exposure = auto_control_ && auto_control_->value != V4L2_EXPOSURE_MANUAL;
    });
  }

  // The source string's (or, after a reconnect, the operator's last) exposure, gain and lock.
  void apply_initial_controls() {
    if (spec_.exposure_ms) hub_->check("exposure_ms", *spec_.exposure_ms, true);
    if (spec_.gain) hub_->check("gain", *spec_.gain, false);
    PendingCameraControls initial;
    initial.auto_exposure = spec_.auto_exposure;
    if (spec_.exposure_ms) initial.auto_exposure = false;
    initial.exposure_ms = spec_.exposure_ms;
    initial.gain = spec_.gain;
    if (spec_.locked) initial.locked = true;
    apply(initial);
  }

  // Runs on the capture thread (or before it starts): the device is only ever touched by one thread.
  void apply(const PendingCameraControls& p) {
    if (p.fps) {
      // UVC cameras take a new rate only while stopped: stop, renegotiate, restart.
      camera_->stop();
      StreamRequest request{camera_->format().layout.format, camera_->format().layout.width, camera_->format().layout.height,
                            *p.fps, spec_.buffer_count};
      camera_->configure(request);
      camera_->start();
      last_sequence_.reset();  // the driver counts from 0 again
      spec_.fps = camera_->format().fps;
      hub_->update([&](CameraState& s) { s.fps = camera_->format().fps; s.fps_range.default_value = s.fps; });
    }
    if (p.auto_exposure && auto_control_) {
      camera_->set_control(V4L2_CID_EXPOSURE_AUTO, *p.auto_exposure ? V4L2_EXPOSURE_APERTURE_PRIORITY : V4L2_EXPOSURE_MANUAL);
      spec_.auto_exposure = *p.auto_exposure;
      hub_->update([&](CameraState& s) { s.auto_exposure = *p.auto_exposure; });
    }
    if (p.locked && *p.locked && auto_control_) {
      camera_->set_control(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL);
      spec_.auto_exposure = false;
      hub_->update([&](CameraState& s) { s.auto_exposure = false; });
    }
    if (p.exposure_ms && exposure_control_) {
      const auto units = static_cast<std::int32_t>(std::lround(*p.exposure_ms / kExposureUnitMs));
      const std::int32_t kept = camera_->set_control(V4L2_CID_EXPOSURE_ABSOLUTE, units);
      spec_.exposure_ms = kept * kExposureUnitMs;
      spec_.auto_exposure = false;
    }
    if (p.gain && gain_control_) {
      const std::int32_t kept = camera_->set_control(V4L2_CID_GAIN, static_cast<std::int32_t>(std::lround(*p.gain)));
      spec_.gain = kept;
    }
    if (p.locked) {
      spec_.locked = *p.locked;
      if (*p.locked) {  // hold what is in effect now, so a reconnect restores it
        if (exposure_control_) spec_.exposure_ms = camera_->get_control(V4L2_CID_EXPOSURE_ABSOLUTE) * kExposureUnitMs;
        if (gain_control_) spec_.gain = camera_->get_control(V4L2_CID_GAIN);
      }
      hub_->update([&](CameraState& s) { s.locked = *p.locked; });
    }
  }

  void describe() {
    const NegotiatedFormat& f = camera_->format();
    info_.kind = "v4l2";
    std::ostringstream d;
    d << spec_.device << " (" << camera_->info().card << (spec_.emulated ? ", emulated" : "") << ") "
      << to_string(f.layout.format) << " " << f.layout.width << "x" << f.layout.height;
    if (f.fps > 0.0) d << " @ " << f.fps << " fps";
    if (spec_.stereo_side_by_side) d << ", side-by-side stereo (left view)";
    info_.description = d.str();
    info_.frame_count.reset();
    info_.live = true;
    info_.nominal_fps = f.fps;
  }

  void stop_thread() {
    stop_requested_ = true;
    frame_ready_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  void capture_loop() {
    while (!stop_requested_) {
      if (!camera_) {
        if (!wait_for_reconnect()) return;
        continue;
      }
      try {
        const PendingCameraControls pending = hub_->take_pending();
        if (pending.any()) {
          try {
            apply(pending);
          } catch (const DeviceGoneError&) {
            throw;
          } catch (const InputError& e) {  // a control the driver refused: the stream goes on
            hub_->update([&](CameraState& s) { s.error = e.what(); });
          }
        }
        if (auto image = camera_->capture(kCaptureWaitMs)) deliver(std::move(*image));
      } catch (const DeviceGoneError& e) {
        on_unplug(e.what());
      } catch (const std::exception& e) {
        spdlog::error("{}", e.what());
        hub_->update([&](CameraState& s) {
          s.connection = CameraConnection::Failed;
          s.error = e.what();
        });
        const std::lock_guard lock(mutex_);
        failure_ = e.what();
        frame_ready_.notify_all();
        return;
      }
    }
    try {
      if (camera_) camera_->stop();
    } catch (const std::exception&) {
      // stopping an unplugged camera: nothing left to stop
    }
  }

  void deliver(CapturedImage image) {
    QueuedFrame q;
    std::int64_t gap = 0;
    if (last_sequence_ && image.sequence > *last_sequence_) gap = static_cast<std::int64_t>(image.sequence) - *last_sequence_ - 1;
    last_sequence_ = image.sequence;
    // The values in effect: read back from the device after the frame, as auto exposure moves them.
    // A device unplugged just after the frame cannot be asked; it cannot have changed them either.
    std::optional<double> exposure_ms = last_exposure_ms_, gain_device = last_gain_device_;
    try {
      if (exposure_control_) exposure_ms = camera_->get_control(V4L2_CID_EXPOSURE_ABSOLUTE) * kExposureUnitMs;
      if (gain_control_) gain_device = camera_->get_control(V4L2_CID_GAIN);
    } catch (const DeviceGoneError&) {
      // the next capture() reports the unplug; this frame is kept
    }
    last_exposure_ms_ = exposure_ms;
    last_gain_device_ = gain_device;
    const std::optional<double> gain = gain_device ? std::optional<double>(*gain_device / gain_unity_) : std::nullopt;
    if (spec_.stereo_side_by_side) {
      StereoPair pair = split_side_by_side(image.image);
      q.frame.image = std::move(pair.left);
      q.right = std::move(pair.right);
    } else {
      q.frame.image = std::move(image.image);
    }
    q.frame.bit_depth = image.bit_depth;
    q.frame.timestamp_s = image.timestamp_s;
    q.frame.exposure_ms = exposure_ms;
    q.frame.gain = gain;
    q.frame.index = captured_++;
    q.frame.name = spec_.device + " #" + std::to_string(image.sequence);

    // The state first, then the frame: a consumer that has the frame sees the state that goes with it.
    const double dt = previous_timestamp_ ? image.timestamp_s - *previous_timestamp_ : 0.0;
    previous_timestamp_ = image.timestamp_s;
    hub_->update([&](CameraState& s) {
      ++s.frames_captured;
      s.frames_dropped_by_driver += gap;
      s.exposure_in_effect_ms = exposure_ms;
      s.gain_in_effect = gain_device;
      s.gain_unity = gain_unity_;
      if (dt > 0.0) {
        const double rate = (gap + 1) / dt;  // frames per second the device produced
        s.measured_fps = s.measured_fps > 0.0 ? 0.9 * s.measured_fps + 0.1 * rate : rate;
      }
    });
    {
      const std::lock_guard lock(mutex_);
      if (static_cast<int>(queue_.size()) >= spec_.queue_capacity) {
        queue_.pop_front();  // a live camera never waits for its consumer
        // Counted under the queue's lock, so a consumer never sees a frame gone and not counted.
        hub_->update([](CameraState& s) { ++s.frames_dropped_by_queue; });
      }
      queue_.push_back(std::move(q));
    }
    frame_ready_.notify_all();
  }

  void on_unplug(const std::string& what) {
    spdlog::warn("{}", what);
    camera_.reset();
    previous_timestamp_.reset();
    {
      const std::lock_guard lock(mutex_);
      unplugged_at_ = Clock::now();
    }
    frame_ready_.notify_all();
    hub_->update([&](CameraState& s) {
      s.connection = CameraConnection::Unplugged;
      s.message = spec_.device + " was unplugged; " + std::to_string(s.frames_captured) +
                  " frames captured before are kept; waiting for it to come back";
    });
  }

  // Watches for the node to come back and reopens it with the settings in effect before.
  // Returns false when the thread should end (stopped, or the stream already ended).
  bool wait_for_reconnect() {
    const auto nodes = io_->device_nodes();
    if (std::find(nodes.begin(), nodes.end(), spec_.device) == nodes.end()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(kCaptureWaitMs));
      return true;
    }
    {
      const std::lock_guard lock(mutex_);
      if (ended_) {
        hub_->update([&](CameraState& s) {
          s.connection = CameraConnection::Stopped;
          s.message = spec_.device + " is back; press Start to resume";
        });
        return false;
      }
    }
    hub_->update([](CameraState& s) { s.connection = CameraConnection::Reconnecting; });
    try {
      open_and_start();
    } catch (const InputError& e) {
      spdlog::warn("reconnecting {}: {}", spec_.device, e.what());
      hub_->update([](CameraState& s) { s.connection = CameraConnection::Unplugged; });
      std::this_thread::sleep_for(std::chrono::milliseconds(4 * kCaptureWaitMs));
      return true;
    }
    {
      const std::lock_guard lock(mutex_);
      unplugged_at_.reset();
    }
    hub_->update([&](CameraState& s) { s.message = spec_.device + " reconnected; streaming again"; });
    return true;
  }

  V4l2SourceSpec spec_;  // the capture thread updates the controls in effect, for a reconnect
  std::shared_ptr<V4l2Io> io_;
  std::shared_ptr<CameraControlHub> hub_;
  SourceInfo info_;
  std::unique_ptr<V4l2Camera> camera_;  // owned by the capture thread while it runs
  std::optional<ControlInfo> exposure_control_, gain_control_, auto_control_;
  double gain_unity_ = 1.0;
  std::optional<std::uint32_t> last_sequence_;
  std::optional<double> previous_timestamp_;
  std::optional<double> last_exposure_ms_, last_gain_device_;  // read back with the previous frame
  std::int64_t captured_ = 0;

  std::thread thread_;
  std::atomic<bool> stop_requested_{false};
  mutable std::mutex mutex_;  // guards the queue and the stream's end
  std::condition_variable frame_ready_;
  std::deque<QueuedFrame> queue_;
  std::string end_reason_;  // why the stream ended, when a camera went away (guarded by mutex_)
  std::optional<Clock::time_point> unplugged_at_;
  bool ended_ = false;
  std::string failure_;
  std::optional<cv::Mat> last_right_;  // consumer side only
};

std::shared_ptr<V4l2Io> emulated_io_for(const V4l2SourceSpec& spec) {
  auto emulator = make_emulated_nir_cameras(spec.emulated_paced);
  if (spec.emulated_frames > 0 && (spec.device == "/dev/video0" || spec.device == "/dev/video2"))
    emulator->unplug_after(spec.device, spec.emulated_frames);
  return emulator;
}

}  // namespace

std::unique_ptr<V4l2Source> open_v4l2_source(const V4l2SourceSpec& spec, std::shared_ptr<V4l2Io> io) {
  return std::make_unique<V4l2SourceImpl>(spec, std::move(io));
}

std::unique_ptr<V4l2Source> open_v4l2_source(const V4l2SourceSpec& spec) {
  return open_v4l2_source(spec, spec.emulated ? emulated_io_for(spec) : make_system_v4l2_io());
}

}  // namespace nirslam
