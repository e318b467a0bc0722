#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "nirslam/illumination/exposure_check.hpp"
#include "nirslam/illumination/sweep_recorder.hpp"
#include "nirslam/illumination/sweep_response.hpp"
#include "nirslam/image/frame.hpp"
#include "nirslam/quality/frame_metrics.hpp"
#include "nirslam/quality/image_quality.hpp"
#include "nirslam/session/recording_status.hpp"
#include "nirslam/sources/source.hpp"
#include "nirslam/worker/photometric_view.hpp"
#include "nirslam/worker/trajectory_view.hpp"

namespace nirslam {

enum class WorkerState { Idle, Running, Paused, Finished, Failed };
const char* to_string(WorkerState state);

// One frame in the history plots: kept small (72 bytes), as a snapshot copies the whole history.
struct QualitySample {
  std::int64_t frame_index = 0;
  double timestamp_s = 0.0;
  ImageQuality quality;
  float gradient_energy = 0.0f;
  float feature_coverage = 0.0f;
  float feature_evenness = 0.0f;
  std::int32_t feature_count = 0;
};

struct StageTimings {
  double read_ms = 0.0;     // pulling the frame from the source (decode included)
  double quality_ms = 0.0;  // every frame metric: histogram pass, gradient energy, FAST corners
  double photometric_ms = 0.0;  // KLT tracks, exposure estimate, correction G(I)/V
  double odometry_ms = 0.0;     // tracking, and on keyframes the window optimisation
  double mapping_ms = 0.0;      // of odometry_ms: window optimisation and point activation
  double total_ms = 0.0;
};

// What the pipeline's stages said about one frame, for per-frame logs.
struct PipelineFrameInfo {
  std::string tracking;                     // odometry status ("tracking", "lost", ...); empty without odometry
  bool keyframe = false;                    // the odometry made this frame a keyframe
  double residual_rms = 0.0;                // of the frame's direct alignment, grey levels
  std::optional<double> exposure_estimate;  // photometric calibration: ms x gain, or relative
};

// What the worker knew after one frame. Published as std::shared_ptr<const Snapshot> and never
// modified afterwards, so readers on other threads need no lock. The frame's pixel buffer is shared
// with the worker, which never writes to a buffer after publishing it.
struct Snapshot {
  std::uint64_t sequence = 0;  // increases by one with every publish
  WorkerState state = WorkerState::Idle;
  SourceInfo source;
  std::optional<Frame> frame;  // the latest processed frame
  ImageQuality quality;        // of `frame`
  ImageStructure structure{};  // of `frame`: sharpness and corner features
  GreyHistogram histogram{};   // of `frame`, 256 bins as the entropy uses them
  FeatureGrid feature_grid{};  // of `frame`: FAST corners per grid cell
  ExposureCheck exposure{};    // of `frame`: clipped / too dark / fine, for the warning banner
  std::vector<QualitySample> quality_history;  // oldest first, bounded length
  StageTimings timings;
  std::int64_t frames_processed = 0;
  std::int64_t frames_dropped = 0;  // live sources only: frames skipped because the pipeline lagged
  double processing_fps = 0.0;      // frames per second over the last second of processing
  std::optional<double> illuminator_power_w;  // the power the operator set, when set
  // The power sweep wizard, the sweeps and the power recommendation. Shared between snapshots
  // until it changes; never null in snapshots the worker publishes.
  std::shared_ptr<const IlluminationStatus> illumination;
  // The camera response fitted from the wizard's last complete sweep (its frames, the rig
  // still): fitting, done or failed. Null before a sweep completes and after a new one starts.
  std::shared_ptr<const SweepResponse> sweep_response;
  PipelineFrameInfo stages;    // of `frame`
  std::string pipeline_mode;   // "quality", "odometry", "calibrated", ... (PipelineMode)
  bool pipeline_mode_automatic = false;  // pipeline_mode was chosen for the source (automatic_pipeline_mode)
  // Why the pipeline could not be built for this source (e.g. a given calibration file it
  // refused); the frames then get image quality only. Empty when it runs.
  std::string pipeline_error;
  // The frame as the odometry saw it: G(I)/V, CV_32FC1 on the 0..255 scale, when the mode corrects
  // frames; empty otherwise. Shares the pipeline's buffer, never written after publishing.
  cv::Mat corrected_image;
  // Photometric calibration and odometry state, shared between snapshots until they change;
  // never null in snapshots the worker publishes.
  std::shared_ptr<const PhotometricView> photometric;
  std::shared_ptr<const TrajectoryView> trajectory;
  // The session recording (command::StartRecording): state, folder, frames written and dropped,
  // bytes, free space and minutes left, the last error. State Off when none was started.
  RecordingStatus recording;
  std::string message;              // last status or error, for the operator
};

// The worker stopped on its own (end of the input or an error): its snapshots no longer change.
inline bool settled(const Snapshot& s) { return s.state == WorkerState::Finished || s.state == WorkerState::Failed; }

}  // namespace nirslam
