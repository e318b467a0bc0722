#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_io.hpp"
#include "nirslam/image/image_files.hpp"
#include "nirslam/sources/sequence_files.hpp"
#include "nirslam/sources/source.hpp"

namespace nirslam {

struct ImageFolderOptions {
  // Frame rate used for timestamps (index / fps) when there is no times file.
  double nominal_fps = 20.0;
  // Times file; when unset, "times.txt" in the folder is used if it exists. Either the TUM form
  // "id timestamp_s [exposure_ms]" (paired with the images in order) or "filename timestamp_s"
  // (the first column names an image file of the folder).
  std::optional<std::filesystem::path> times_file;
  // Camera file (DSO camera.txt); when unset, "camera.txt" in the folder is used if it exists.
  std::optional<std::filesystem::path> camera_file;
};

// A folder of image files, taken in natural order of their names.
class ImageFolderReader final : public Source {
public:
  explicit ImageFolderReader(const std::filesystem::path& folder, ImageFolderOptions options = {});

  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override;
  void rewind() override { next_index_ = 0; }
  void seek(std::size_t position) override {
    require_frame_position(position, files_.size());
    next_index_ = position;
  }
  std::shared_ptr<const CameraModel> camera() const override;

  const std::optional<DsoCameraCalibration>& calibration() const { return calibration_; }
  const std::vector<std::filesystem::path>& image_files() const { return files_; }
  // Whether timestamps came from a times file (else they are index / nominal_fps).
  bool has_recorded_timestamps() const { return has_times_; }

private:
  std::filesystem::path folder_;
  SourceInfo info_;
  std::vector<std::filesystem::path> files_;
  std::vector<double> timestamps_s_;
  std::vector<std::optional<double>> exposures_ms_;
  bool has_times_ = false;
  std::optional<DsoCameraCalibration> calibration_;
  GreyImageDecoder decoder_;
  std::size_t next_index_ = 0;
};

}  // namespace nirslam
