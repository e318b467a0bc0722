#include "nirslam/sources/euroc_reader.hpp"

#include <charconv>
#include <fstream>

#include <spdlog/spdlog.h>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"

namespace nirslam {

namespace fs = std::filesystem;

namespace {

// The camera folder (the one holding data.csv) for a dataset root, a mav0 folder or itself.
fs::path find_camera_folder(const fs::path& path, const std::string& camera) {
  if (!fs::exists(path)) throw InputError(path, "does not exist");
  if (!fs::is_directory(path)) throw InputError(path, "is not a folder");
  for (const fs::path& candidate : {path / "mav0" / camera, path / camera, path})
    if (fs::is_regular_file(candidate / "data.csv")) return candidate;
  throw InputError(path, "not a EuRoC folder: found none of mav0/" + camera + "/data.csv, " +
                             camera + "/data.csv, data.csv");
}

}  // namespace

double seconds_from_nanoseconds(std::int64_t nanoseconds) {
  // Both parts carry the sign (C++ division truncates towards zero), so no digits cancel.
  constexpr std::int64_t kPerSecond = 1'000'000'000;
  const std::int64_t seconds = nanoseconds / kPerSecond;
  const std::int64_t remainder = nanoseconds % kPerSecond;
  return static_cast<double>(seconds) + static_cast<double>(remainder) * 1e-9;
}

EurocReader::EurocReader(const fs::path& path, EurocOptions options)
    : camera_folder_(find_camera_folder(path, options.camera)) {
  const fs::path csv = camera_folder_ / "data.csv";
  const fs::path data_folder = camera_folder_ / "data";
  std::ifstream in(csv);
  if (!in) throw InputError(csv, "cannot open");
  int number = 0;
  for (std::string text; std::getline(in, text);) {
    ++number;
    const std::string_view line = trim(text);
    if (line.empty() || line.front() == '#') continue;
    const std::size_t comma = line.find(',');
    if (comma == std::string_view::npos || line.find(',', comma + 1) != std::string_view::npos)
      throw InputError(csv, number, "expected 'timestamp_ns,filename'");
    const std::string_view stamp = trim(line.substr(0, comma));
    const std::string filename(trim(line.substr(comma + 1)));
    std::int64_t nanoseconds = 0;
    const auto [end, error] = std::from_chars(stamp.data(), stamp.data() + stamp.size(), nanoseconds);
    if (stamp.empty() || error != std::errc() || end != stamp.data() + stamp.size())
      throw InputError(csv, number, "timestamp '" + std::string(stamp) +
                                        "' is not an integer number of nanoseconds");
    if (nanoseconds < 0) throw InputError(csv, number, "timestamp is negative");
    if (!timestamps_ns_.empty() && nanoseconds <= timestamps_ns_.back())
      throw InputError(csv, number, "timestamp is not after the previous line's");
    if (filename.empty()) throw InputError(csv, number, "file name is empty");
    const fs::path file = data_folder / filename;
    if (!fs::is_regular_file(file))
      throw InputError(csv, number, "image '" + filename + "' does not exist in " + data_folder.string());
    timestamps_ns_.push_back(nanoseconds);
    files_.push_back(file);
  }
  if (in.bad()) throw InputError(csv, "read error");
  if (files_.empty()) throw InputError(csv, "lists no images");

  const fs::path sensor_file = camera_folder_ / "sensor.yaml";
  if (fs::exists(sensor_file)) {
    sensor_ = read_euroc_sensor_yaml(sensor_file);
    decoder_.expect_size(sensor_->camera->width(), sensor_->camera->height(), sensor_file.string());
  } else {
    spdlog::warn("{}: no sensor.yaml; the sequence has no geometric calibration",
                 camera_folder_.string());
  }

  std::vector<double> seconds;
  for (const std::int64_t ns : timestamps_ns_) seconds.push_back(seconds_from_nanoseconds(ns));
  info_.kind = "euroc";
  info_.description = camera_folder_.string();
  info_.frame_count = files_.size();
  info_.live = false;
  info_.seekable = true;
  info_.nominal_fps = sensor_ && sensor_->rate_hz ? *sensor_->rate_hz
                                                  : frame_rate_from_timestamps(seconds);
}

std::shared_ptr<const CameraModel> EurocReader::camera() const {
  return sensor_ ? sensor_->camera : nullptr;
}

std::optional<Frame> EurocReader::next() {
  if (next_index_ >= files_.size()) return std::nullopt;
  // Advance first: after a bad frame throws, the next call moves on to the following one.
  const std::size_t index = next_index_++;
  GreyImageDecoder::Image decoded = decoder_.read_file(files_[index]);
  return make_sequence_frame(std::move(decoded), index, seconds_from_nanoseconds(timestamps_ns_[index]), std::nullopt,
                             files_[index].filename().string());
}

}  // namespace nirslam
