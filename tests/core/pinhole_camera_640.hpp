#pragma once
// The 640 x 480 pinhole camera (f = 500 px, principal point at the centre) that the lamp-distance
// tests share.

#include <Eigen/Core>

#include "nirslam/camera/camera_model.hpp"

namespace nirslam {

inline PinholeCamera pinhole_camera_640() { return PinholeCamera(640, 480, Eigen::Vector4d(500.0, 500.0, 320.0, 240.0)); }

}  // namespace nirslam
