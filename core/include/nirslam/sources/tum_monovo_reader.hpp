#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "nirslam/camera/camera_io.hpp"
#include "nirslam/sources/image_folder_reader.hpp"
#include "nirslam/sources/source.hpp"

namespace nirslam {

// One line of a TUM monoVO times.txt: "id timestamp_s [exposure_ms]".
struct TimesEntry {
  std::string id;  // the first column, as written (TUM: the image number, "00042")
  double timestamp_s = 0.0;
  std::optional<double> exposure_ms;
  int line = 0;  // 1-based line in the file, for messages
};

// Reads a times file: blank lines and lines starting with '#' are skipped; every other line has
// 2 or 3 columns, a finite timestamp and a positive exposure when present. Throws InputError
// naming the file and line of the first bad line.
std::vector<TimesEntry> read_times_file(const std::filesystem::path& file);

// Throws InputError naming the first line whose timestamp is earlier than the line before it.
void require_time_order(const std::vector<TimesEntry>& entries, const std::filesystem::path& file);

// The illuminator power per image from a frames.csv beside times.txt (what `nirslam simulate`
// writes: a header naming the columns, among them `file` and `illuminator_power_w`), keyed by the
// image's file name. Empty when the header has no such columns. Throws InputError naming the
// file and line of a line with too few fields or a power that is not a non-negative number.
std::unordered_map<std::string, double> read_frame_powers(const std::filesystem::path& file);

// A TUM monoVO sequence folder (the layout DSO reads):
//   images/ or images.zip   the frames, paired in natural name order with the lines of times.txt
//   times.txt               "id timestamp_s exposure_ms" (exposure optional per line); required
//   camera.txt              DSO camera file; optional (a warning is logged when it is missing)
//   pcalib.txt, vignette.png  photometric calibration; only their paths are recorded here
//   frames.csv              optional; its illuminator_power_w column goes to each frame
// Frames are decoded one at a time in next(); a zip archive stays open and members are read on
// demand. When both images/ and images.zip exist, images/ is used.
class TumMonoVoReader final : public Source {
public:
  explicit TumMonoVoReader(const std::filesystem::path& folder);
  ~TumMonoVoReader() override;

  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override;
  void rewind() override { next_index_ = 0; }
  void seek(std::size_t position) override {
    require_frame_position(position, times_.size());
    next_index_ = position;
  }
  std::shared_ptr<const CameraModel> camera() const override;

  const std::filesystem::path& folder() const { return folder_; }
  const std::optional<DsoCameraCalibration>& calibration() const { return calibration_; }
  const std::vector<TimesEntry>& times() const { return times_; }
  // Paths of the photometric calibration files when the folder has them.
  const std::optional<std::filesystem::path>& response_file() const { return pcalib_file_; }
  const std::optional<std::filesystem::path>& vignette_file() const { return vignette_file_; }
  // Whether the frames come from images.zip.
  bool reads_zip() const { return archive_ != nullptr; }

private:
  class ZipArchive;

  std::filesystem::path folder_;
  SourceInfo info_;
  std::vector<TimesEntry> times_;
  std::vector<std::optional<double>> powers_w_;  // per image, from frames.csv
  std::optional<DsoCameraCalibration> calibration_;
  std::optional<std::filesystem::path> pcalib_file_;
  std::optional<std::filesystem::path> vignette_file_;
  std::vector<std::filesystem::path> image_files_;  // when reading images/
  std::unique_ptr<ZipArchive> archive_;             // when reading images.zip
  GreyImageDecoder decoder_;
  std::size_t next_index_ = 0;
};

}  // namespace nirslam
