#include "nirslam/sources/sequence_files.hpp"

namespace nirslam {

namespace fs = std::filesystem;

std::optional<DsoCameraCalibration> read_optional_dso_camera(const fs::path& file) {
  if (!fs::exists(file)) return std::nullopt;
  return read_dso_camera_file(file);
}

double frame_rate_from_timestamps(const std::vector<double>& timestamps_s) {
  if (timestamps_s.size() < 2) return 0.0;
  const double span = timestamps_s.back() - timestamps_s.front();
  if (!(span > 0.0)) return 0.0;
  return static_cast<double>(timestamps_s.size() - 1) / span;
}

}  // namespace nirslam
