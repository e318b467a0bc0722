#pragma once

// Writes simulated sequences to disk in TUM monoVO layout, with every ground truth beside them:
//
//   images/00000.png ...  8- or 16-bit grey frames
//   times.txt             "id timestamp_s exposure_ms" (DSO's format)
//   camera.txt            DSO camera file: "Pinhole fx fy cx cy 0" / "FOV fx fy cx cy omega",
//                         "w h", "none" (pinhole) or "crop" (FOV), "w h"
//   pcalib.txt            the inverse response G, 256 values in grey levels
//   vignette.png          V(x), 16-bit, scaled to its maximum
//   groundtruth.txt       TUM trajectory: "timestamp tx ty tz qx qy qz qw", T_world_cam
//   frames.csv            per frame: file, time, exposure, gain, illuminator power, mean grey
//   groundtruth.json      every parameter: scene, seed, camera, response coefficients and G,
//                         vignette, illuminator (power, offset, beam), noise, exposure mode
//   depth/00000.png       optional: z of each pixel's centre ray, 16-bit millimetres (0: none)
//
// A power sweep writes the same, with each viewpoint rendered at every power, plus sweep.csv.
// Every write failure (a full disk) throws std::runtime_error naming the file.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/sim/simulator.hpp"

namespace nirslam {

struct SimulationOutput {
  bool write_depth = false;
  std::optional<std::filesystem::path> contact_sheet;  // a PNG of a few frames, for a look
  int contact_sheet_frames = 6;
  int contact_sheet_columns = 3;
  int contact_sheet_tile_width = 320;
};

struct SequenceSummary {
  std::filesystem::path folder;
  std::int64_t images = 0;
  double duration_s = 0.0;
  double min_exposure_ms = 0.0, max_exposure_ms = 0.0;
  double mean_grey = 0.0;  // over all frames, fraction of full scale
  double render_seconds = 0.0;
};

// Called after each image with (images written, images in all).
using SimulationProgress = std::function<void(std::int64_t, std::int64_t)>;

// Renders options.frames frames (which must be > 0) into `folder` (created if needed).
SequenceSummary write_simulated_sequence(const SimulatorOptions& options, const std::filesystem::path& folder,
                                         const SimulationOutput& output = {}, const SimulationProgress& progress = {});

struct PowerSweepOptions {
  std::vector<double> powers_w;   // each viewpoint at each of these
  std::int64_t viewpoints = 1;    // from frames 0, stride, 2 stride, ... of the trajectory
  std::int64_t stride = 30;
  int settle_frames = 40;         // auto exposure: frames to settle at each power before the one kept
};

// The same viewpoint(s) at a list of powers: images/ in viewpoint-major order, sweep.csv
// ("file,viewpoint,frame_index,timestamp_s,power_w,exposure_ms,gain,mean_grey"), and the rest as
// write_simulated_sequence (times.txt repeats a viewpoint's timestamp for each power).
SequenceSummary write_power_sweep(const SimulatorOptions& options, const PowerSweepOptions& sweep,
                                  const std::filesystem::path& folder, const SimulationOutput& output = {},
                                  const SimulationProgress& progress = {});

// DSO camera.txt for a pinhole or FOV camera (see the layout above). Throws std::runtime_error
// naming the file on a write failure, std::invalid_argument for other camera models.
void write_dso_camera_file(const std::filesystem::path& file, const CameraModel& camera);

// Frames side by side, `columns` a row, each scaled to tile_width, labelled; 8-bit grey.
cv::Mat make_contact_sheet(const std::vector<cv::Mat>& frames, const std::vector<std::string>& labels, int columns,
                           int tile_width);

}  // namespace nirslam
