#pragma once

#include <memory>
#include <optional>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "nirslam/camera/camera_model.hpp"
#include "nirslam/image/frame.hpp"

namespace nirslam {

// How to choose the pinhole camera that undistorted images are rendered into; the third and
// fourth lines of DSO's camera.txt.
enum class RectificationMode {
  Crop,      // largest pinhole view in which every output pixel has a source pixel (DSO "crop")
  Full,      // pinhole view that contains the whole input image; corners stay empty (DSO "full")
  SameK,     // the input's fx fy cx cy and size (DSO "none": no resampling for a pinhole input)
  Explicit,  // given intrinsics and size
};

struct RectificationSpec {
  RectificationMode mode = RectificationMode::Crop;
  int width = 0;   // output size; 0 x 0 means the input size (SameK always uses the input size)
  int height = 0;
  Eigen::Vector4d intrinsics = Eigen::Vector4d::Zero();  // Explicit only: fx fy cx cy in pixels
};

// DSO's "relative" intrinsics (fractions of the image size, pixel (0,0) covering [0,1]^2) to
// pixels with centres at integer coordinates: fx w, fy h, cx w - 0.5, cy h - 0.5.
Eigen::Vector4d absolute_from_relative_intrinsics(const Eigen::Vector4d& relative, int width,
                                                  int height);

// The output pinhole for a spec; throws std::invalid_argument when it cannot be built (a size
// that is not positive, a crop that finds no valid region, a full view wider than 180 degrees).
PinholeCamera make_output_pinhole(const CameraModel& input, const RectificationSpec& spec);

// The pinhole of a given size whose view is the largest axis-aligned rectangle of the z = 1 plane
// whose border, and so (for the usual lenses) whose whole area, maps inside the input image.
PinholeCamera make_crop_pinhole(const CameraModel& input, int width, int height);

// The pinhole of a given size whose view just contains every ray of the input image's border.
PinholeCamera make_full_pinhole(const CameraModel& input, int width, int height);

// A pinhole with the input's intrinsics and size.
PinholeCamera make_same_k_pinhole(const CameraModel& input);

// Resamples images of one camera model into a pinhole camera. The map from each output pixel to
// its source position in the input image is computed once; each image then costs one bilinear
// cv::remap. Output pixels whose ray does not land where bilinear interpolation is defined in the
// input ([0, w-1] x [0, h-1]) are 0, and valid_mask() tells them apart from dark pixels.
// Immutable after construction, so one instance may serve several threads.
class Undistorter {
public:
  Undistorter(const CameraModel& input, const PinholeCamera& output);
  Undistorter(const CameraModel& input, const RectificationSpec& spec);

  const CameraModel& input_camera() const { return *input_; }
  const PinholeCamera& output_camera() const { return output_; }

  // CV_8UC1 of the output size: 255 where the output pixel has a source, 0 where it has none.
  const cv::Mat& valid_mask() const { return valid_mask_; }
  double valid_fraction() const;

  // True when the input is a pinhole with the output's size and intrinsics: undistort() copies.
  bool is_identity() const { return identity_; }

  // Source position (input pixel coordinates) of each output pixel, CV_32FC1; -1 where invalid.
  const cv::Mat& map_x() const { return map_x_; }
  const cv::Mat& map_y() const { return map_y_; }

  // A new CV_8UC1 or CV_16UC1 image of the output size. Throws std::invalid_argument when the
  // image is not of the input camera's size or not single-channel 8/16-bit.
  cv::Mat undistort(const cv::Mat& image) const;

  // The same frame (timestamp, exposure, gain, power, name, bit depth) with the image undistorted.
  Frame undistort(const Frame& frame) const;

private:
  std::shared_ptr<const CameraModel> input_;
  PinholeCamera output_;
  bool identity_ = false;
  cv::Mat map_x_;
  cv::Mat map_y_;
  cv::Mat fixed_map_xy_;     // CV_16SC2, cv::convertMaps of map_x_/map_y_: the fast remap path
  cv::Mat fixed_map_frac_;   // CV_16UC1 interpolation table indices
  cv::Mat valid_mask_;
};

}  // namespace nirslam
