#pragma once

// A power sweep on disk: a folder of images and sweep.csv naming each image's illuminator power.
//
//   sweep.csv   a header line naming the columns, then one line per image. Required columns:
//               `file` (the image, relative to the folder) and `power_w` (watts, >= 0); optional
//               `scene` (a scene type or alias of config/illumination.yaml). Other columns are
//               ignored, so the simulator's sweep.csv ("file,viewpoint,frame_index,timestamp_s,
//               power_w,exposure_ms,gain,mean_grey", written by `nirslam simulate --sweep`) is read
//               as it is. Blank lines and lines starting with '#' are skipped.
//
// Without a scene column the scene may come from the simulator's groundtruth.json ("scene":
// {"kind": ...}) beside sweep.csv. Several images at one power (several viewpoints or frames) are
// averaged.

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "nirslam/illumination/sweep.hpp"
#include "nirslam/quality/frame_metrics.hpp"

namespace nirslam {

struct SweepImage {
  std::filesystem::path file;  // absolute or relative to the working directory (folder / column)
  double power_w = 0.0;
  std::string scene;           // empty when sweep.csv has no scene column
  int line = 0;                // in sweep.csv
};

struct SweepFolder {
  std::filesystem::path folder;
  std::filesystem::path table;  // folder / "sweep.csv"
  std::vector<SweepImage> images;
  std::optional<std::string> ground_truth_scene;  // groundtruth.json's scene.kind, when present
};

// Reads sweep.csv. Throws InputError naming sweep.csv and the line: a missing table or header
// column, a row with the wrong number of fields, an empty file name, a power that is not a number
// >= 0, an image that does not exist, a table without images.
SweepFolder read_sweep_folder(const std::filesystem::path& folder);

// Measures every image of the folder and records it at its power, per scene: images with a scene
// of their own under it, the others under `default_scene`. Decoding errors throw InputError naming
// the image and the sweep.csv line.
std::map<std::string, SweepRecord> measure_sweep(const SweepFolder& folder, QualityMeter& meter,
                                                 const std::string& default_scene);

}  // namespace nirslam
