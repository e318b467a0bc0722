#pragma once

// Real calibrations used as test cameras across the camera tests.

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/camera/undistorter.hpp"

namespace nirslam::test_cameras {

// EuRoC MAV cam0 (sensor.yaml of V1_01_easy).
inline RadTanCamera euroc_cam0() {
  return RadTanCamera(752, 480, {458.654, 457.296, 367.215, 248.375},
                      {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05});
}

// The TUM monoVO camera.txt of sequence 01: relative FOV calibration of a 1280x1024 sensor.
inline FovCamera tum_monovo_fov() {
  return FovCamera(1280, 1024,
                   absolute_from_relative_intrinsics({0.349153, 0.436593, 0.493140, 0.499021}, 1280,
                                                     1024),
                   0.933271);
}

// A TUM-VI style fish-eye (Kannala-Brandt, 190 degrees lens) on a 512x512 sensor.
inline EquidistantCamera tumvi_fisheye() {
  return EquidistantCamera(512, 512, {190.97847715128717, 190.9733070521226, 254.93170605935475,
                                      256.8974428996504},
                           {0.0034823894022493434, 0.0007150348452162257, -0.0020532361418706202,
                            0.00020293673591811182});
}

}  // namespace nirslam::test_cameras
