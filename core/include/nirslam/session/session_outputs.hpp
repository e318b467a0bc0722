#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "nirslam/photometric/calibration_output.hpp"

namespace nirslam {

class SlamPipeline;

// What the pipeline ended with, written into a folder (a session or a run's output):
// trajectory.txt, keyframes.txt, points.ply when the odometry ran, calibration/ when the online
// photometric calibration ran. Returns the names written. Throws std::runtime_error naming the file.
std::vector<std::string> write_pipeline_outputs(const SlamPipeline& pipeline, const std::filesystem::path& folder,
                                                const CalibrationOutputInfo& info);

}  // namespace nirslam
