#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "nirslam/image/frame.hpp"
#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

class CameraModel;

// The photometric parameters a source was made with, when it knows them (the simulator).
struct PhotometricTruth {
  ResponseModel response;
  VignetteModel vignette;  // the lens's
  // When a co-located lamp lights the scene: the lens vignetting times the lamp's beam pattern
  // (the halo factor), which is what a calibration under that lamp estimates as its vignette.
  std::optional<VignetteModel> halo;
};
class IlluminatorController;
class CameraControls;

struct SourceInfo {
  std::string kind;         // "tum", "euroc", "folder", "demo", "v4l2", "session", ...
  std::string description;  // what an operator recognises: a path, a device, a scene
  std::optional<std::size_t> frame_count;  // known for datasets, unknown for live sources
  bool live = false;        // a live source keeps producing frames whether or not they are consumed
  double nominal_fps = 0.0; // recorded or device rate, 0 when unknown
  std::string scene_type;   // "room", "outdoor", "parking", "tunnel" when the source knows it
  bool seekable = false;    // seek() jumps to any frame (datasets and recorded sessions)
  // The frames carry the co-located lamp's power (Frame::illuminator_power_w), above zero in at
  // least one of them (a live source: at opening): what the automatic pipeline mode asks.
  bool reports_lamp_power = false;
};

// A stream of frames. Datasets, cameras, recorded sessions and the simulator all implement it.
// Not thread-safe: one consumer (the worker) pulls frames.
class Source {
public:
  virtual ~Source() = default;
  Source() = default;
  Source(const Source&) = delete;
  Source& operator=(const Source&) = delete;

  virtual const SourceInfo& info() const = 0;

  // The next frame, or std::nullopt at the end of the stream. A frame that cannot be read throws
  // nirslam::InputError naming the file; a frame of the wrong size or depth is such a frame.
  virtual std::optional<Frame> next() = 0;

  // Back to the first frame. Live sources restart streaming.
  virtual void rewind() = 0;

  // The next next() returns the frame at `position` (0-based, as Frame::index). Throws
  // std::out_of_range naming the source past its last frame, and std::logic_error for a source
  // that cannot seek (info().seekable is false: live cameras, the simulator).
  virtual void seek(std::size_t position);

  // Why next() returned the end when it was not the end of a recording (a camera unplugged and not
  // back in time): the worker reports it instead of "end of sequence". Empty for datasets.
  virtual std::string end_reason() const { return {}; }

  // Frames the source itself had to discard because its consumer lagged (live sources drop the
  // oldest queued frame rather than block); 0 for datasets, which are read frame by frame.
  virtual std::int64_t frames_dropped() const { return 0; }

  // The geometric camera model, when the source carries a calibration; nullptr otherwise.
  virtual std::shared_ptr<const CameraModel> camera() const { return nullptr; }

  // The illuminator, when the source drives its own (the demo's virtual lamp; the simulator's can
  // be wired the same way); nullptr otherwise (the operator sets a real lamp by hand). The worker
  // sends the operator's power to it, and the frames then report the power they were taken at.
  // Called on the worker thread.
  virtual std::shared_ptr<IlluminatorController> illuminator() const { return nullptr; }
  // The camera's exposure, gain and lock, when the source has a camera to control (a V4L2 camera,
  // the simulator's); thread-safe, shared so it may outlive the source.
  virtual std::shared_ptr<CameraControls> camera_controls() const { return nullptr; }
  // The true response and vignette, when the source knows them (for overlays and evaluation).
  virtual std::optional<PhotometricTruth> photometric_truth() const { return std::nullopt; }

protected:
  // For seek(): throws std::out_of_range naming the source when `position` is not below its
  // frame count.
  void require_frame_position(std::size_t position, std::size_t frame_count) const;
};

}  // namespace nirslam
