#include "nirslam/session/session_outputs.hpp"

#include "nirslam/pipeline/slam_pipeline.hpp"
#include "nirslam/session/odometry_output.hpp"
#include "nirslam/session/session_format.hpp"

namespace nirslam {

std::vector<std::string> write_pipeline_outputs(const SlamPipeline& pipeline, const std::filesystem::path& folder,
                                                const CalibrationOutputInfo& info) {
  std::vector<std::string> written;
  if (const DirectOdometry* odometry = pipeline.odometry()) {
    write_trajectory_tum(folder / session_files::kTrajectory, odometry->trajectory());
    write_keyframes(folder / session_files::kKeyframes, odometry->keyframes());
    write_points_ply(folder / session_files::kPoints, odometry->points());
    written.insert(written.end(), {session_files::kTrajectory, session_files::kKeyframes, session_files::kPoints});
  }
  if (const OnlinePhotometricCalibration* calibration = pipeline.calibration()) {
    write_calibration_output(folder / session_files::kCalibration, *calibration->estimate(),
                             calibration->exposure_history(), info, std::nullopt);
    written.push_back(std::string(session_files::kCalibration) + "/");
  }
  return written;
}

}  // namespace nirslam
