#pragma once

#include <string>

#include "nirslam/worker/worker.hpp"

namespace nirslam::app {

// What a SOURCE argument on the command line names: the word "demo" for the built-in sequence, or
// a dataset path (TUM monoVO, EuRoC, image folder). The path is checked now, so a typo is reported
// before any window opens; the source itself is opened on the worker thread.
SourceFactory source_factory_from_argument(const std::string& argument);

inline constexpr const char* kSourceArgumentHelp =
    "'demo' (built-in sequence) or a dataset folder: TUM monoVO, EuRoC (mav0/cam0) or a folder of "
    "images";

}  // namespace nirslam::app
