#pragma once

#include <filesystem>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/camera/undistorter.hpp"

namespace nirslam {

// What a DSO / TUM monoVO camera.txt says: the input camera and how to rectify it.
//
//   line 1: the input model, one of
//             fx fy cx cy omega               FOV ("ATAN") model; omega = 0 means pinhole
//             fx fy cx cy k1 k2 p1 p2         RadTan (DSO's legacy 8-number form)
//             Pinhole fx fy cx cy [0]
//             FOV fx fy cx cy omega
//             RadTan fx fy cx cy k1 k2 p1 p2
//             EquiDistant fx fy cx cy k1 k2 k3 k4   (or KannalaBrandt ...: the same model)
//           with fx fy cx cy relative to the image size when cx < 1 and cy < 1 (DSO's rule;
//           converted with absolute_from_relative_intrinsics, which subtracts 0.5 px).
//   line 2: input width height
//   line 3: crop | full | none | fx fy cx cy [0]  (the last relative to the output size)
//   line 4: output width height
// Keywords are matched case-insensitively; lines starting with '#' are skipped.
struct DsoCameraCalibration {
  std::shared_ptr<const CameraModel> input;
  RectificationSpec output;  // width/height always set from line 4
};

// Throws InputError naming the file and line for anything it does not understand.
DsoCameraCalibration read_dso_camera_file(const std::filesystem::path& file);
// The same from a stream; `file` only names the source in errors.
DsoCameraCalibration parse_dso_camera(std::istream& in, const std::filesystem::path& file);

// A camera's sensor.yaml in the EuRoC / Kalibr ASL layout.
struct EurocCameraSensor {
  std::shared_ptr<const CameraModel> camera;
  // T_BS: maps points from the sensor (camera) frame to the body (IMU) frame.
  Eigen::Matrix4d T_body_sensor = Eigen::Matrix4d::Identity();
  std::optional<double> rate_hz;
  std::string comment;
};

// Reads camera_model (pinhole), intrinsics [fu, fv, cu, cv], resolution [w, h], distortion_model
// (radial-tangential | radtan | equidistant | none) with distortion_coefficients, and the
// optional T_BS, rate_hz and comment. The "%YAML:1.0" header that OpenCV writes (and yaml-cpp
// rejects) is accepted. Throws InputError naming the file and the field (or the line for YAML
// syntax errors).
EurocCameraSensor read_euroc_sensor_yaml(const std::filesystem::path& file);

}  // namespace nirslam
