#pragma once

// What every dataset reader reads beside its images.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "nirslam/camera/camera_io.hpp"
#include "nirslam/image/frame.hpp"
#include "nirslam/image/image_files.hpp"

namespace nirslam {

// Reads an optional camera file beside images: DSO camera.txt. std::nullopt when absent.
std::optional<DsoCameraCalibration> read_optional_dso_camera(const std::filesystem::path& file);

// Frames per second implied by a sequence of timestamps: (n - 1) / (last - first); 0 when that
// is not defined (fewer than two frames or no time span).
double frame_rate_from_timestamps(const std::vector<double>& timestamps_s);

// The frame a dataset reader hands out for its `index`-th decoded image.
Frame make_sequence_frame(GreyImageDecoder::Image decoded, std::size_t index, double timestamp_s,
                          std::optional<double> exposure_ms, std::string name);

}  // namespace nirslam
