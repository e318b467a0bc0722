#pragma once

#include <filesystem>
#include <fstream>

#include "nirslam/worker/snapshot.hpp"

namespace nirslam {

// Per-frame metrics as CSV, one row per processed frame, flushed row by row so a crash or a full
// disk loses at most the row being written. A failed write throws std::runtime_error naming the
// file, instead of leaving a silently truncated table.
class MetricsCsvWriter {
public:
  explicit MetricsCsvWriter(std::filesystem::path path);
  void write(const Snapshot& snapshot);
  const std::filesystem::path& path() const { return path_; }
  std::int64_t rows() const { return rows_; }

  static constexpr const char* kHeader =
      "frame_index,timestamp_s,exposure_ms,illuminator_power_w,entropy_bits,saturated_fraction,"
      "black_fraction,read_ms,quality_ms,mean,rms_contrast,gradient_energy,feature_count,feature_coverage,"
      "feature_evenness,photometric_ms,odometry_ms,mapping_ms,exposure_estimate,tracking,keyframe,residual_rms";

private:
  void check(const char* what);

  std::filesystem::path path_;
  std::ofstream out_;
  std::int64_t rows_ = 0;
};

}  // namespace nirslam
