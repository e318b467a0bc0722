#include "nirslam/sources/tum_monovo_reader.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include <spdlog/spdlog.h>
#include <zip.h>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"

namespace nirslam {

namespace fs = std::filesystem;


void require_time_order(const std::vector<TimesEntry>& entries, const fs::path& file) {
  for (std::size_t i = 1; i < entries.size(); ++i)
    if (entries[i].timestamp_s < entries[i - 1].timestamp_s)
      throw InputError(file, entries[i].line,
                       "timestamp goes backwards (line " + std::to_string(entries[i - 1].line) +
                           " has a later one)");
}

std::vector<TimesEntry> read_times_file(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, fs::exists(file) ? "cannot open times file" : "times file is missing");
  std::vector<TimesEntry> entries;
  int number = 0;
  for (std::string text; std::getline(in, text);) {
    ++number;
    std::istringstream stream(text);
    std::vector<std::string> tokens;
    for (std::string token; stream >> token;) tokens.push_back(token);
    if (tokens.empty() || tokens.front().front() == '#') continue;
    if (tokens.size() < 2 || tokens.size() > 3)
      throw InputError(file, number,
                       "expected 'id timestamp_s [exposure_ms]', got " +
                           std::to_string(tokens.size()) + " column(s)");
    TimesEntry entry;
    entry.id = tokens[0];
    entry.line = number;
    const std::optional<double> timestamp = parse_double(tokens[1]);
    if (!timestamp)
      throw InputError(file, number, "timestamp '" + tokens[1] + "' is not a number");
    entry.timestamp_s = *timestamp;
    if (tokens.size() == 3) {
      const std::optional<double> exposure = parse_double(tokens[2]);
      if (!exposure) throw InputError(file, number, "exposure '" + tokens[2] + "' is not a number");
      if (!(*exposure > 0.0))
        throw InputError(file, number,
                         "exposure must be positive milliseconds (leave the column out when unknown)");
      entry.exposure_ms = *exposure;
    }
    entries.push_back(std::move(entry));
  }
  if (in.bad()) throw InputError(file, "read error");
  return entries;
}

std::unordered_map<std::string, double> read_frame_powers(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open frames file");
  std::unordered_map<std::string, double> powers;
  std::optional<std::size_t> file_column, power_column;
  std::size_t columns = 0;
  int number = 0;
  for (std::string text; std::getline(in, text);) {
    ++number;
    if (trim(text).empty() || trim(text).front() == '#') continue;
    const std::vector<std::string_view> fields = split_fields(text);
    if (columns == 0) {  // the header
      columns = fields.size();
      for (std::size_t c = 0; c < fields.size(); ++c) {
        if (fields[c] == "file") file_column = c;
        if (fields[c] == "illuminator_power_w") power_column = c;
      }
      if (!file_column || !power_column) return powers;
      continue;
    }
    if (fields.size() != columns)
      throw InputError(file, number, "expected " + std::to_string(columns) + " fields as the header has, got " +
                                         std::to_string(fields.size()));
    const std::string_view power_text = fields[*power_column];
    const std::optional<double> power = parse_double(power_text);
    if (!power || !(*power >= 0.0))
      throw InputError(file, number, "illuminator_power_w '" + std::string(power_text) +
                                         "' is not a non-negative number of watts");
    powers[fs::path(std::string(fields[*file_column])).filename().string()] = *power;
  }
  if (in.bad()) throw InputError(file, "read error");
  return powers;
}

// ---------------------------------------------------------------------------------------------

// The image members of a zip archive, in natural name order, read one at a time.
class TumMonoVoReader::ZipArchive {
public:
  explicit ZipArchive(const fs::path& file) : file_(file) {
    int error_code = 0;
    archive_ = zip_open(file.c_str(), ZIP_RDONLY, &error_code);
    if (archive_ == nullptr) {
      zip_error_t error;
      zip_error_init_with_code(&error, error_code);
      const std::string message = zip_error_strerror(&error);
      zip_error_fini(&error);
      throw InputError(file, "cannot open zip archive: " + message);
    }
    const zip_int64_t count = zip_get_num_entries(archive_, 0);
    for (zip_int64_t i = 0; i < count; ++i) {
      const char* name = zip_get_name(archive_, static_cast<zip_uint64_t>(i), 0);
      if (name == nullptr) continue;
      const std::string member(name);
      if (member.empty() || member.back() == '/' || !is_image_file_name(member)) continue;
      members_.push_back(Member{static_cast<zip_uint64_t>(i), member});
    }
    std::sort(members_.begin(), members_.end(),
              [](const Member& a, const Member& b) { return natural_less(a.name, b.name); });
  }
  ~ZipArchive() { zip_discard(archive_); }  // opened read-only: nothing to write back
  ZipArchive(const ZipArchive&) = delete;
  ZipArchive& operator=(const ZipArchive&) = delete;

  std::size_t size() const { return members_.size(); }
  const std::string& name(std::size_t k) const { return members_[k].name; }
  // How a member is named in messages: the archive's path followed by the member's name.
  fs::path member_path(std::size_t k) const { return file_ / members_[k].name; }

  std::vector<unsigned char> read(std::size_t k) const {
    const Member& member = members_[k];
    zip_stat_t stat;
    zip_stat_init(&stat);
    if (zip_stat_index(archive_, member.index, 0, &stat) != 0 || (stat.valid & ZIP_STAT_SIZE) == 0)
      throw InputError(member_path(k), "cannot read zip member: " + std::string(zip_strerror(archive_)));
    constexpr zip_uint64_t kMaxImageBytes = zip_uint64_t{1} << 30;  // a corrupt header, not a frame
    if (stat.size > kMaxImageBytes)
      throw InputError(member_path(k), "zip member claims " + std::to_string(stat.size) + " bytes");
    zip_file_t* handle = zip_fopen_index(archive_, member.index, 0);
    if (handle == nullptr)
      throw InputError(member_path(k), "cannot open zip member: " + std::string(zip_strerror(archive_)));
    std::vector<unsigned char> bytes(static_cast<std::size_t>(stat.size));
    const zip_int64_t read = bytes.empty() ? 0 : zip_fread(handle, bytes.data(), stat.size);
    std::string message;
    if (read < 0) message = zip_file_strerror(handle);
    zip_fclose(handle);
    if (read < 0) throw InputError(member_path(k), "cannot read zip member: " + message);
    if (static_cast<zip_uint64_t>(read) != stat.size)
      throw InputError(member_path(k), "zip member is truncated");
    return bytes;
  }

private:
  struct Member {
    zip_uint64_t index;
    std::string name;
  };
  fs::path file_;
  zip_t* archive_ = nullptr;
  std::vector<Member> members_;
};

// ---------------------------------------------------------------------------------------------

TumMonoVoReader::TumMonoVoReader(const fs::path& folder) : folder_(folder) {
  if (!fs::exists(folder)) throw InputError(folder, "folder does not exist");
  if (!fs::is_directory(folder)) throw InputError(folder, "is not a folder");

  // The frames: images/ first (what the TUM archives unpack to), else images.zip.
  std::size_t image_count = 0;
  std::string images_origin;
  if (fs::is_directory(folder / "images")) {
    image_files_ = list_image_files(folder / "images");
    image_count = image_files_.size();
    images_origin = (folder / "images").string();
  } else if (fs::is_regular_file(folder / "images.zip")) {
    archive_ = std::make_unique<ZipArchive>(folder / "images.zip");
    image_count = archive_->size();
    images_origin = (folder / "images.zip").string();
  } else {
    throw InputError(folder, "not a TUM monoVO folder: it has neither images/ nor images.zip");
  }
  if (image_count == 0) throw InputError(images_origin, "holds no image files");

  const fs::path times_file = folder / "times.txt";
  if (!fs::exists(times_file))
    throw InputError(times_file,
                     "missing: a TUM monoVO folder needs 'id timestamp_s [exposure_ms]' per image "
                     "(to read the images without timestamps, open the images folder itself)");
  times_ = read_times_file(times_file);
  require_time_order(times_, times_file);
  if (times_.size() != image_count)
    throw InputError(times_file, "has " + std::to_string(times_.size()) + " timestamp lines but " +
                                     images_origin + " has " + std::to_string(image_count) +
                                     " images");
  // Lines pair with images by order. When both the id and the file name are numbers they must
  // agree: a gap or a stray file would otherwise shift every timestamp silently.
  for (std::size_t i = 0; i < image_count; ++i) {
    const std::string image_name = archive_ ? archive_->name(i) : image_files_[i].filename().string();
    const std::optional<long long> id = parse_integer<long long>(times_[i].id);
    const std::optional<long long> number = parse_integer<long long>(fs::path(image_name).stem().string());
    if (id && number && *id != *number)
      throw InputError(times_file, times_[i].line,
                       "id " + times_[i].id + " does not match image " + image_name +
                           " (times.txt lines pair with the images in name order)");
  }

  // The lamp's power per frame, where the folder says it (the simulator's frames.csv): the
  // illuminator modes use it, and a lamp that is on tells the odometry that the exposure alone
  // does not explain the brightness.
  powers_w_.assign(image_count, std::nullopt);
  if (const fs::path frames_file = folder / "frames.csv"; fs::exists(frames_file)) {
    const auto powers = read_frame_powers(frames_file);
    for (std::size_t i = 0; i < image_count && !powers.empty(); ++i) {
      const std::string image_name = archive_ ? archive_->name(i) : image_files_[i].filename().string();
      if (const auto it = powers.find(fs::path(image_name).filename().string()); it != powers.end()) powers_w_[i] = it->second;
    }
  }

  calibration_ = read_optional_dso_camera(folder / "camera.txt");
  if (calibration_) {
    decoder_.expect_size(calibration_->input->width(), calibration_->input->height(),
                         (folder / "camera.txt").string());
  } else {
    spdlog::warn("{}: no camera.txt; the sequence has no geometric calibration", folder.string());
  }
  if (fs::exists(folder / "pcalib.txt")) pcalib_file_ = folder / "pcalib.txt";
  if (fs::exists(folder / "vignette.png")) vignette_file_ = folder / "vignette.png";

  std::vector<double> timestamps;
  for (const TimesEntry& entry : times_) timestamps.push_back(entry.timestamp_s);
  info_.kind = "tum";
  info_.description = folder.string();
  info_.frame_count = image_count;
  info_.live = false;
  info_.seekable = true;
  info_.nominal_fps = frame_rate_from_timestamps(timestamps);
  info_.reports_lamp_power =
      std::any_of(powers_w_.begin(), powers_w_.end(), [](const std::optional<double>& p) { return p && *p > 0.0; });
}

TumMonoVoReader::~TumMonoVoReader() = default;

std::shared_ptr<const CameraModel> TumMonoVoReader::camera() const {
  return calibration_ ? calibration_->input : nullptr;
}

std::optional<Frame> TumMonoVoReader::next() {
  if (next_index_ >= times_.size()) return std::nullopt;
  // Advance first: after a bad frame throws, the next call moves on to the following one.
  const std::size_t index = next_index_++;
  GreyImageDecoder::Image decoded =
      archive_ ? decoder_.decode(archive_->read(index), archive_->member_path(index))
               : decoder_.read_file(image_files_[index]);
  Frame frame = make_sequence_frame(std::move(decoded), index, times_[index].timestamp_s, times_[index].exposure_ms,
                                    archive_ ? archive_->name(index) : image_files_[index].filename().string());
  frame.illuminator_power_w = powers_w_[index];
  return frame;
}

}  // namespace nirslam
