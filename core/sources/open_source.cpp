#include "nirslam/sources/open_source.hpp"

#include <system_error>

#include "nirslam/common/error.hpp"
#include "nirslam/sources/euroc_reader.hpp"
#include "nirslam/sources/image_folder_reader.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"

namespace nirslam {

namespace fs = std::filesystem;

std::string_view to_string(SourceFormat format) {
  switch (format) {
    case SourceFormat::TumMonoVo: return "TUM monoVO";
    case SourceFormat::Euroc: return "EuRoC";
    case SourceFormat::ImageFolder: return "image folder";
  }
  return "unknown";
}

std::optional<SourceFormat> detect_source_format(const fs::path& path) {
  std::error_code error;
  const fs::file_status status = fs::status(path, error);
  if (!fs::exists(status)) throw InputError(path, "does not exist");
  if (!fs::is_directory(status)) {
    if (is_image_file_name(path))
      throw InputError(path, "is a single image, not a sequence: give the folder that holds the images");
    throw InputError(path, "is a file, not a dataset folder (TUM monoVO, EuRoC or a folder of images)");
  }
  const EurocOptions euroc;
  if (fs::is_regular_file(path / "mav0" / euroc.camera / "data.csv") ||
      fs::is_regular_file(path / euroc.camera / "data.csv") ||
      (fs::is_regular_file(path / "data.csv") && fs::is_directory(path / "data")))
    return SourceFormat::Euroc;
  if (fs::is_directory(path / "images") || fs::is_regular_file(path / "images.zip"))
    return SourceFormat::TumMonoVo;
  for (const fs::directory_entry& entry : fs::directory_iterator(path, error))
    if (entry.is_regular_file(error) && is_image_file_name(entry.path()))
      return SourceFormat::ImageFolder;
  if (error) throw InputError(path, "cannot list folder: " + error.message());
  return std::nullopt;
}

std::unique_ptr<Source> open_source(const fs::path& path) {
  const std::optional<SourceFormat> format = detect_source_format(path);
  if (!format)
    throw InputError(path,
                     "not a recognised sequence: expected a TUM monoVO folder (images/ or "
                     "images.zip with times.txt), a EuRoC folder (mav0/cam0/data.csv) or a folder "
                     "of image files");
  switch (*format) {
    case SourceFormat::TumMonoVo: return std::make_unique<TumMonoVoReader>(path);
    case SourceFormat::Euroc: return std::make_unique<EurocReader>(path);
    case SourceFormat::ImageFolder: return std::make_unique<ImageFolderReader>(path);
  }
  throw InputError(path, "unknown source format");
}

}  // namespace nirslam
