#pragma once
// How the odometry fits the surface normals for the lamp's cos(theta) (surface_normals.hpp), as
// an option of the public odometry API.

#include <optional>
#include <string_view>

namespace nirslam {

// How a point's normal is fitted to its neighbours.
//   Spread: the direction of least spread of their 3-D positions, where they are flat enough.
//   InverseDepthPlane: the plane rho = a + b x + c y (least squares in the inverse depth rho over
//     their normalised image coordinates, the form in which the depths are estimated), where
//     they spread in both image directions (min_spread_ratio on their image coordinates) and the
//     fit holds (max_relative_residual). Where the depths scatter, the spread's flatness test
//     leaves most points without a normal (their lamp factor then has no cos(theta)); this gives
//     one nearly everywhere, noisier per point (IlluminatorFactor.SurfaceNormalsUnderDepthNoise*).
//     Table 2's lamp mode over three start frames (36 runs): geometric mean ATE 0.0175 -> 0.0164 m,
//     better on 20 of 36, but the rooms worse in all 9 (README "Illuminator correction", session
//     28): an option. (The spread's normal where it finds a plane and the inverse-depth plane's
//     elsewhere was tried too: 0.0178, not kept.)
enum class SurfaceNormalFit { Spread, InverseDepthPlane };
std::string_view to_string(SurfaceNormalFit fit);
std::optional<SurfaceNormalFit> surface_normal_fit_from_string(std::string_view text);

}  // namespace nirslam
