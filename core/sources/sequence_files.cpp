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

Frame make_sequence_frame(GreyImageDecoder::Image decoded, std::size_t index, double timestamp_s,
                          std::optional<double> exposure_ms, std::string name) {
  Frame frame;
  frame.image = std::move(decoded.image);
  frame.bit_depth = decoded.bit_depth;
  frame.timestamp_s = timestamp_s;
  frame.index = static_cast<std::int64_t>(index);
  frame.exposure_ms = exposure_ms;
  frame.name = std::move(name);
  return frame;
}

}  // namespace nirslam
