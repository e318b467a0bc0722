#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string_view>

#include "nirslam/sources/source.hpp"

namespace nirslam {

enum class SourceFormat {
  TumMonoVo,    // images/ or images.zip (+ times.txt, camera.txt)
  Euroc,        // mav0/cam0/data.csv, from the dataset root, mav0 or cam0
  ImageFolder,  // image files directly in the folder
};

std::string_view to_string(SourceFormat format);

// Which reader a path is for, by what the folder contains (checked in the order EuRoC, TUM
// monoVO, image folder). std::nullopt for a folder that matches none. Throws InputError when the
// path does not exist or is a file: a single image (or any file) is not a sequence.
std::optional<SourceFormat> detect_source_format(const std::filesystem::path& path);

// Opens the dataset at `path` with the reader its layout calls for. Throws InputError naming the
// path when it does not exist, is not a folder, or matches no known layout, and whatever the
// reader throws for a malformed dataset.
std::unique_ptr<Source> open_source(const std::filesystem::path& path);

}  // namespace nirslam
