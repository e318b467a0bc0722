#pragma once

// The EuRoC V1_01 excerpt among the real camera data the tests use (../shared/data/README.md).

#include <filesystem>

namespace nirslam {

inline const std::filesystem::path kEurocMicro = std::filesystem::path(NIRSLAM_SHARED_DATA_DIR) / "euroc_v1_01_micro";

}  // namespace nirslam
