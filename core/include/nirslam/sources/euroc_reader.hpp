#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "nirslam/camera/camera_io.hpp"
#include "nirslam/sources/image_folder_reader.hpp"
#include "nirslam/sources/source.hpp"

namespace nirslam {

// Nanoseconds since the epoch to seconds. Whole seconds and the remainder are converted apart:
// a double holds 1.4e18 ns only to ~256 ns, but 1.4e9 s plus a fraction to ~0.24 us, so this
// keeps every digit a double can keep and consecutive frames' differences exact to < 1 us.
double seconds_from_nanoseconds(std::int64_t nanoseconds);

struct EurocOptions {
  std::string camera = "cam0";  // which camera folder under mav0/
};

// One camera of a EuRoC MAV (ASL) sequence:
//   mav0/<camera>/data.csv     "#timestamp [ns],filename" header, then "timestamp_ns,filename"
//   mav0/<camera>/data/        the images
//   mav0/<camera>/sensor.yaml  intrinsics and distortion; optional (warning when missing)
// The path may be the dataset root, its mav0 folder or the camera folder itself.
// data.csv is read and every listed image checked to exist when the reader opens; the images
// are decoded one at a time in next().
class EurocReader final : public Source {
public:
  explicit EurocReader(const std::filesystem::path& path, EurocOptions options = {});

  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override;
  void rewind() override { next_index_ = 0; }
  void seek(std::size_t position) override {
    require_frame_position(position, files_.size());
    next_index_ = position;
  }
  std::shared_ptr<const CameraModel> camera() const override;

  const std::filesystem::path& camera_folder() const { return camera_folder_; }
  const std::optional<EurocCameraSensor>& sensor() const { return sensor_; }
  // The timestamps exactly as data.csv writes them.
  const std::vector<std::int64_t>& timestamps_ns() const { return timestamps_ns_; }
  const std::vector<std::filesystem::path>& image_files() const { return files_; }

private:
  std::filesystem::path camera_folder_;
  SourceInfo info_;
  std::vector<std::int64_t> timestamps_ns_;
  std::vector<std::filesystem::path> files_;
  std::optional<EurocCameraSensor> sensor_;
  GreyImageDecoder decoder_;
  std::size_t next_index_ = 0;
};

}  // namespace nirslam
