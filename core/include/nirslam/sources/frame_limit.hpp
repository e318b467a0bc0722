#pragma once

#include <cstdint>
#include <memory>

#include "nirslam/sources/source.hpp"

namespace nirslam {

// Ends `source` after `max_frames` frames (for quick runs on long sequences).
std::unique_ptr<Source> limit_frames(std::unique_ptr<Source> source, std::int64_t max_frames);

}  // namespace nirslam
