#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>

namespace nirslam {

// Geometric camera models: a lens distortion on the normalised image plane, then intrinsics K.
//
// Conventions, shared by every model and every function of this folder:
// - Camera frame: x right, y down, z forward (optical axis). Only points with z > 0 project.
// - Pixel coordinates: the centre of pixel (col, row) is at (col, row), as in OpenCV and in DSO
//   after its 0.5 shift of relative calibrations. The image covers [-0.5, w-0.5] x [-0.5, h-0.5];
//   bilinear interpolation is defined on [0, w-1] x [0, h-1].
// - Every model maps a 3-D point p to "distorted normalised coordinates" m (a 2-vector on the
//   z = 1 plane after distortion), then to pixels with u = fx * m.x + cx, v = fy * m.y + cy.
//   The model-specific part is only p -> m and its inverse.

enum class CameraModelType { Pinhole, RadTan, Fov, Equidistant };

// The keyword DSO's camera.txt uses for the model: "Pinhole", "RadTan", "FOV", "EquiDistant".
std::string_view to_string(CameraModelType type);

using Matrix23d = Eigen::Matrix<double, 2, 3>;

class CameraModel {
public:
  virtual ~CameraModel() = default;

  CameraModelType type() const { return type_; }
  std::string_view name() const { return to_string(type_); }

  int width() const { return width_; }
  int height() const { return height_; }
  double fx() const { return intrinsics_[0]; }
  double fy() const { return intrinsics_[1]; }
  double cx() const { return intrinsics_[2]; }
  double cy() const { return intrinsics_[3]; }
  // (fx, fy, cx, cy), the order of DSO's and EuRoC's files.
  const Eigen::Vector4d& intrinsics() const { return intrinsics_; }
  Eigen::Matrix3d K() const;

  // The distortion parameters in the order the files write them (empty for the pinhole):
  // RadTan (k1, k2, p1, p2), FOV (omega), Equidistant (k1, k2, k3, k4).
  virtual Eigen::VectorXd distortion() const = 0;

  // Pixel of a point given in camera coordinates. std::nullopt when the point is behind the
  // camera (z <= 0) or outside the domain where the model is one-to-one (a distortion polynomial
  // that folds back). The image bounds are not checked: see contains().
  // With `d_pixel_d_point`, also writes the 2x3 Jacobian of the pixel with respect to p_cam.
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_cam,
                                         Matrix23d* d_pixel_d_point = nullptr) const;

  // The viewing ray through a pixel, scaled so that z = 1. std::nullopt when no ray in front of
  // the camera maps to the pixel (beyond the model's valid domain, or the iterative inverse of
  // the distortion did not converge).
  std::optional<Eigen::Vector3d> unproject(const Eigen::Vector2d& pixel) const;

  // Whether a pixel lies where bilinear interpolation is defined, at least `border` pixels in.
  bool contains(const Eigen::Vector2d& pixel, double border = 0.0) const;

  virtual std::unique_ptr<CameraModel> clone() const = 0;

  // One line for logs: "RadTan 752x480 fx=458.654 fy=457.296 cx=367.215 cy=248.375 dist=[...]".
  std::string describe() const;

protected:
  // Throws std::invalid_argument unless the size is positive and fx, fy > 0, all finite.
  CameraModel(CameraModelType type, int width, int height, const Eigen::Vector4d& fx_fy_cx_cy);
  CameraModel(const CameraModel&) = default;
  CameraModel& operator=(const CameraModel&) = default;

  // p (z > 0) -> distorted normalised m, with dm/dp when asked. std::nullopt outside the domain.
  virtual std::optional<Eigen::Vector2d> distort_point(const Eigen::Vector3d& p_cam,
                                                       Matrix23d* dm_dp) const = 0;
  // Distorted normalised m -> undistorted normalised (x, y) of the ray (x, y, 1).
  virtual std::optional<Eigen::Vector2d> undistort_normalised(const Eigen::Vector2d& m) const = 0;

private:
  CameraModelType type_;
  int width_;
  int height_;
  Eigen::Vector4d intrinsics_;
};

// The ideal perspective camera: m = (x/z, y/z).
class PinholeCamera final : public CameraModel {
public:
  PinholeCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy);

  Eigen::VectorXd distortion() const override { return Eigen::VectorXd(); }
  std::unique_ptr<CameraModel> clone() const override;

private:
  std::optional<Eigen::Vector2d> distort_point(const Eigen::Vector3d& p_cam,
                                               Matrix23d* dm_dp) const override;
  std::optional<Eigen::Vector2d> undistort_normalised(const Eigen::Vector2d& m) const override;
};

// Radial-tangential ("plumb bob") distortion with k1, k2, p1, p2, as OpenCV and EuRoC define it.
// With (x, y) = (X/Z, Y/Z) and r^2 = x^2 + y^2:
//   m_x = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   m_y = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y
// The radial polynomial r (1 + k1 r^2 + k2 r^4) stops growing at some radius for many real
// calibrations (k1 < 0); beyond it the model folds back and a pixel has two rays. Points beyond
// that radius do not project, so project() and unproject() stay inverse to each other.
class RadTanCamera final : public CameraModel {
public:
  RadTanCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy,
               const Eigen::Vector4d& k1_k2_p1_p2);

  double k1() const { return coefficients_[0]; }
  double k2() const { return coefficients_[1]; }
  double p1() const { return coefficients_[2]; }
  double p2() const { return coefficients_[3]; }
  Eigen::VectorXd distortion() const override { return coefficients_; }
  std::unique_ptr<CameraModel> clone() const override;

  // Squared undistorted radius up to which the radial polynomial is monotonic (may be +inf).
  double max_radius_squared() const { return max_radius_squared_; }

  // Undistorted normalised (x, y) -> distorted normalised m, with the 2x2 Jacobian when asked.
  Eigen::Vector2d distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* dm_dxy = nullptr) const;

private:
  std::optional<Eigen::Vector2d> distort_point(const Eigen::Vector3d& p_cam,
                                               Matrix23d* dm_dp) const override;
  std::optional<Eigen::Vector2d> undistort_normalised(const Eigen::Vector2d& m) const override;

  Eigen::Vector4d coefficients_;
  double max_radius_squared_;
};

// The FOV ("ATAN") model of Devernay and Faugeras, as DSO and PTAM use it, with one parameter
// omega (the field of view of an ideal fish-eye lens, radians, 0 < omega < pi):
//   r_d = atan(2 r_u tan(omega / 2)) / omega,  m = (r_d / r_u) (x, y).
// It has a closed-form inverse r_u = tan(r_d omega) / (2 tan(omega / 2)), valid for
// r_d omega < pi/2, which unproject() uses instead of an iteration.
class FovCamera final : public CameraModel {
public:
  FovCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy, double omega);

  double omega() const { return omega_; }
  Eigen::VectorXd distortion() const override;
  std::unique_ptr<CameraModel> clone() const override;

private:
  std::optional<Eigen::Vector2d> distort_point(const Eigen::Vector3d& p_cam,
                                               Matrix23d* dm_dp) const override;
  std::optional<Eigen::Vector2d> undistort_normalised(const Eigen::Vector2d& m) const override;

  double omega_;
  double two_tan_half_omega_;  // 2 tan(omega / 2), the slope of the model at the centre * omega
};

// The equidistant fish-eye model of Kannala and Brandt with k1..k4, as EuRoC/Kalibr
// ("equidistant"), Basalt ("kb4"), OpenCV's fisheye module and DSO ("EquiDistant",
// "KannalaBrandt") define it. With theta the angle between the ray and the optical axis:
//   theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
//   m = (theta_d / r_u) (x, y),  with (x, y) = (X/Z, Y/Z), r_u = sqrt(x^2 + y^2) = tan(theta).
// Rays are limited to theta < pi/2 (a pinhole-style ray with z = 1 cannot express more) and to
// the range where theta_d grows with theta.
class EquidistantCamera final : public CameraModel {
public:
  EquidistantCamera(int width, int height, const Eigen::Vector4d& fx_fy_cx_cy,
                    const Eigen::Vector4d& k1_k2_k3_k4);

  Eigen::VectorXd distortion() const override { return coefficients_; }
  std::unique_ptr<CameraModel> clone() const override;

  // Largest ray angle (radians, at most pi/2) over which theta_d(theta) is increasing.
  double max_theta() const { return max_theta_; }

  // theta -> theta_d, and d theta_d / d theta when asked.
  double distort_angle(double theta, double* d_thetad_d_theta = nullptr) const;

private:
  std::optional<Eigen::Vector2d> distort_point(const Eigen::Vector3d& p_cam,
                                               Matrix23d* dm_dp) const override;
  std::optional<Eigen::Vector2d> undistort_normalised(const Eigen::Vector2d& m) const override;

  Eigen::Vector4d coefficients_;
  double max_theta_;
};

}  // namespace nirslam
