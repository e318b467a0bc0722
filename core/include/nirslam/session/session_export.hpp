#pragma once
// `nirslam export`: a recorded session as something others can use.
//
//   OUT/images/00000.png ...   the frames, lossless PNG (copied bit for bit when recorded as PNG)
//   OUT/times.txt              "id timestamp_s exposure_ms" (TUM monoVO; exposure when recorded)
//   OUT/camera.txt             DSO camera file, when the session has a calibration
//   OUT/pcalib.txt, vignette.png  when the session holds a photometric calibration (and the
//                              calibration's own files under OUT/calibration/)
//   OUT/trajectory.txt, keyframes.txt, points.ply   when the session holds them (TUM, PLY)
//   OUT/groundtruth.txt        TUM, when the source knew the true poses (simulator)
//   OUT/frames.csv             per frame: timestamp, exposure, gain, illuminator power, entropy
//   OUT/metrics.csv            the worker's full per-frame metrics, when recorded
//   OUT/report.html + OUT/report/*.png   the report and its plots
//   OUT.zip                    everything above in one archive, on request
// The folder is the TUM monoVO layout DSO-family tools (and TumMonoVoReader) read.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace nirslam {

struct ExportOptions {
  bool archive = false;  // also write OUT.zip beside OUT
};

struct ExportSummary {
  std::filesystem::path folder;
  std::optional<std::filesystem::path> archive;
  std::int64_t frames = 0;
  std::vector<std::string> files;  // relative to the folder, in writing order
  std::vector<std::string> plots;  // report/*.png
  std::string evaluation;          // the ATE headline when ground truth and a trajectory exist
  std::vector<std::string> notes;  // what could not be included, and why
};

// Throws InputError naming the file for a session that cannot be read (state "recording": run
// recover first) or an output folder that exists and is not empty; std::runtime_error naming the
// file when a write fails.
ExportSummary export_session(const std::filesystem::path& session, const std::filesystem::path& out,
                             const ExportOptions& options = {});

}  // namespace nirslam
