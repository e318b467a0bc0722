#pragma once

// A candidate point whose inverse depth is still an interval [min, max] (DSO's ImmaturePoint).
// Each new frame searches the epipolar segment the interval maps to, one pixel at a time, for
// the pattern's best photometric match, refines it by Gauss-Newton along the line and shrinks
// the interval to the match +- its pixel uncertainty. The uncertainty grows when the image
// gradient is nearly perpendicular to the epipolar line (the aperture problem).

#include <array>
#include <cstdint>
#include <limits>

#include <Eigen/Core>

#include "nirslam/geometry/se3.hpp"
#include "nirslam/odometry/image_pyramid.hpp"
#include "nirslam/odometry/photometric_residual.hpp"

namespace nirslam::odometry {

enum class TraceStatus { Uninitialised, Good, Skipped, BadCondition, OutOfBounds, Outlier };

struct TraceOptions {
  double max_search_px = 30.0;
  double huber_threshold = 9.0;
  double outlier_energy = 12.0 * 12.0;  // per pattern pixel
  double min_segment_px = 1.5;          // shorter: the interval is as good as a trace can make it
};

class ImmaturePoint {
public:
  ImmaturePoint(const Eigen::Vector2i& pixel, const PyramidLevel& host);

  // Traces into `target` with the pose T_target_host and brightness transfer. With `lamp`
  // enabled, each candidate's brightness transfer also carries the lamp's factor at the inverse
  // depth that candidate means (photometric_residual.hpp), as the window's residuals do: without
  // it the search matched host patches against targets whose brightness differs by the lamp's
  // distance and beam ratios, which a global affine transfer cannot hold.
  TraceStatus trace(const LevelCamera& camera, const PyramidLevel& target, const SE3& T_target_host,
                    const AffineTransfer& affine, const TraceOptions& options, const LampGeometry& lamp = {});

  const Eigen::Vector2d& pixel() const { return pixel_; }
  const std::array<float, kPatternSize>& host_intensity() const { return host_intensity_; }
  double inverse_depth_min() const { return inverse_depth_min_; }
  double inverse_depth_max() const { return inverse_depth_max_; }
  bool bounded() const { return std::isfinite(inverse_depth_max_); }
  double quality() const { return quality_; }
  double last_interval_px() const { return last_interval_px_; }
  TraceStatus last_status() const { return last_status_; }
  int outliers() const { return outliers_; }

private:
  Eigen::Vector2d pixel_;
  std::array<float, kPatternSize> host_intensity_{};
  Eigen::Matrix2d host_structure_ = Eigen::Matrix2d::Zero();  // sum of g g^T over the pattern
  double inverse_depth_min_ = 0.0;
  double inverse_depth_max_ = std::numeric_limits<double>::infinity();
  double quality_ = 10000.0;
  double last_interval_px_ = 1000.0;
  TraceStatus last_status_ = TraceStatus::Uninitialised;
  int outliers_ = 0;
};

}  // namespace nirslam::odometry
