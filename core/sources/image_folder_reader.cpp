#include "nirslam/sources/image_folder_reader.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <system_error>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "nirslam/common/error.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"

namespace nirslam {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// ImageFolderReader

ImageFolderReader::ImageFolderReader(const fs::path& folder, ImageFolderOptions options)
    : folder_(folder) {
  if (!(options.nominal_fps > 0.0) || !std::isfinite(options.nominal_fps))
    throw std::invalid_argument("ImageFolderOptions::nominal_fps must be positive");
  if (!fs::exists(folder)) throw InputError(folder, "folder does not exist");
  if (!fs::is_directory(folder)) throw InputError(folder, "is not a folder");
  files_ = list_image_files(folder);
  if (files_.empty())
    throw InputError(folder, "no image files (png, jpg, pgm, ppm) in the folder");

  if (options.camera_file) {
    calibration_ = read_dso_camera_file(*options.camera_file);
  } else {
    calibration_ = read_optional_dso_camera(folder / "camera.txt");
  }
  if (calibration_) {
    const fs::path camera_file = options.camera_file.value_or(folder / "camera.txt");
    decoder_.expect_size(calibration_->input->width(), calibration_->input->height(),
                         camera_file.string());
  }

  std::optional<fs::path> times_file = options.times_file;
  if (!times_file && fs::exists(folder / "times.txt")) times_file = folder / "times.txt";
  exposures_ms_.assign(files_.size(), std::nullopt);
  if (times_file) {
    const std::vector<TimesEntry> entries = read_times_file(*times_file);
    const bool by_name = !entries.empty() && is_image_file_name(entries.front().id);
    for (const TimesEntry& entry : entries)
      if (is_image_file_name(entry.id) != by_name)
        throw InputError(*times_file, entry.line,
                         "mixes image file names and frame ids in the first column");
    if (!by_name) {
      // TUM form: line i belongs to image i.
      require_time_order(entries, *times_file);
      if (entries.size() != files_.size())
        throw InputError(*times_file, "has " + std::to_string(entries.size()) +
                                          " timestamp lines but the folder has " +
                                          std::to_string(files_.size()) + " images");
      for (std::size_t i = 0; i < entries.size(); ++i) {
        timestamps_s_.push_back(entries[i].timestamp_s);
        exposures_ms_[i] = entries[i].exposure_ms;
      }
    } else {
      // "filename timestamp": look every image up by name.
      std::map<std::string, const TimesEntry*> by_file;
      for (const TimesEntry& entry : entries) {
        if (!by_file.emplace(entry.id, &entry).second)
          throw InputError(*times_file, entry.line, "lists '" + entry.id + "' twice");
        if (!fs::exists(folder / entry.id))
          throw InputError(*times_file, entry.line,
                           "names '" + entry.id + "', which is not an image in " + folder.string());
      }
      const TimesEntry* previous = nullptr;
      for (std::size_t i = 0; i < files_.size(); ++i) {
        const auto found = by_file.find(files_[i].filename().string());
        if (found == by_file.end())
          throw InputError(*times_file, "has no timestamp for image " + files_[i].filename().string() +
                                            " (" + std::to_string(entries.size()) + " lines, " +
                                            std::to_string(files_.size()) + " images)");
        const TimesEntry& entry = *found->second;
        if (previous != nullptr && entry.timestamp_s < previous->timestamp_s)
          throw InputError(*times_file, entry.line,
                           "timestamp of '" + entry.id + "' is earlier than that of '" +
                               previous->id + "', which comes first in name order");
        timestamps_s_.push_back(entry.timestamp_s);
        exposures_ms_[i] = entry.exposure_ms;
        previous = &entry;
      }
      if (by_file.size() != files_.size())
        throw InputError(*times_file, "has " + std::to_string(entries.size()) +
                                          " timestamp lines but the folder has " +
                                          std::to_string(files_.size()) + " images");
    }
    has_times_ = true;
  } else {
    for (std::size_t i = 0; i < files_.size(); ++i)
      timestamps_s_.push_back(static_cast<double>(i) / options.nominal_fps);
  }

  info_.kind = "folder";
  info_.description = folder.string();
  info_.frame_count = files_.size();
  info_.live = false;
  info_.seekable = true;
  info_.nominal_fps = has_times_ ? frame_rate_from_timestamps(timestamps_s_) : options.nominal_fps;
}

std::shared_ptr<const CameraModel> ImageFolderReader::camera() const {
  return calibration_ ? calibration_->input : nullptr;
}

std::optional<Frame> ImageFolderReader::next() {
  if (next_index_ >= files_.size()) return std::nullopt;
  // Advance first: after a bad frame throws, the next call moves on to the following one.
  const std::size_t index = next_index_++;
  GreyImageDecoder::Image decoded = decoder_.read_file(files_[index]);
  return make_sequence_frame(std::move(decoded), index, timestamps_s_[index], exposures_ms_[index],
                             files_[index].filename().string());
}

}  // namespace nirslam
