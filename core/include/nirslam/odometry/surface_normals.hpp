#pragma once

// Local surface normals of the window's points, for the lamp's cos(theta) (photometric_residual.hpp):
// a plane fitted to each point's neighbours in its host keyframe (by pixel distance, at similar
// depth), its normal the direction of least spread. Sparse DSO points have no normals of their
// own; their neighbours' inverse depths are the only local geometry the odometry has.

#include <vector>

#include "nirslam/odometry/image_pyramid.hpp"
#include "nirslam/odometry/surface_normal_fit.hpp"
#include "nirslam/odometry/window_optimizer.hpp"

namespace nirslam::odometry {

struct SurfaceNormalOptions {
  // Neighbours within this many mean point spacings (sqrt(image area / points)) in the image:
  // about 20 neighbours where the points are spread evenly.
  double radius_spacings = 2.5;
  int min_neighbours = 6;             // including the point itself
  double max_relative_depth_gap = 0.15;  // |z_j - z_i| / z_i above: another surface
  double max_flatness = 0.08;         // smallest / middle eigenvalue of the spread; above: not a plane
  double min_spread_ratio = 0.15;     // middle / largest eigenvalue; below: the points lie along a line
  SurfaceNormalFit fit = SurfaceNormalFit::Spread;
  // The inverse-depth plane's fit must hold within this (rms of rho's residuals over the mean rho).
  double max_relative_residual = 0.1;
};

// Sets (or clears) `normal` of every point hosted by one keyframe: unit, in the host frame,
// facing the camera.
void estimate_surface_normals(const LevelCamera& camera, std::vector<WindowPoint>& points,
                              const SurfaceNormalOptions& options = {});

}  // namespace nirslam::odometry
