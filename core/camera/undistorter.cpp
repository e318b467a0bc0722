#include "nirslam/camera/undistorter.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

namespace nirslam {

namespace {

void require_output_size(int width, int height) {
  // Two pixels per axis at least: the view spans (size - 1) pixel steps.
  if (width < 2 || height < 2)
    throw std::invalid_argument("output image size must be at least 2x2, got " +
                                std::to_string(width) + "x" + std::to_string(height));
}

// The pinhole whose pixel 0 sees x = min and pixel size-1 sees x = max on the z = 1 plane.
PinholeCamera pinhole_spanning(double min_x, double max_x, double min_y, double max_y, int width,
                               int height) {
  const double fx = (width - 1) / (max_x - min_x);
  const double fy = (height - 1) / (max_y - min_y);
  return PinholeCamera(width, height, Eigen::Vector4d(fx, fy, -min_x * fx, -min_y * fy));
}

}  // namespace

Eigen::Vector4d absolute_from_relative_intrinsics(const Eigen::Vector4d& relative, int width,
                                                  int height) {
  // DSO assumes a relative calibration treats pixel (0,0) as the area [0,1]^2, while pixel
  // values sample the intensity at the pixel centre: hence the shift by half a pixel.
  return Eigen::Vector4d(relative[0] * width, relative[1] * height, relative[2] * width - 0.5,
                         relative[3] * height - 0.5);
}

PinholeCamera make_same_k_pinhole(const CameraModel& input) {
  return PinholeCamera(input.width(), input.height(), input.intrinsics());
}

PinholeCamera make_crop_pinhole(const CameraModel& input, int width, int height) {
  require_output_size(width, height);
  const auto lands_inside = [&input](double x, double y) {
    const std::optional<Eigen::Vector2d> pixel = input.project(Eigen::Vector3d(x, y, 1.0));
    return pixel && input.contains(*pixel);
  };
  if (!lands_inside(0.0, 0.0))
    throw std::invalid_argument("crop rectification: the optical axis does not hit the image");

  // 1. How far the four half-axes through the optical axis stay inside the image: a first,
  //    too generous rectangle (its corners usually fall outside for barrel distortion).
  const auto axis_extent = [&lands_inside](double dx, double dy) {
    constexpr double kStep = 1e-3;  // normalised units, ~0.5 px at f = 500
    constexpr double kMax = 20.0;   // 87 degrees off axis, beyond any pinhole view worth having
    double last_inside = 0.0;
    for (double s = kStep; s <= kMax; s += kStep) {
      if (!lands_inside(s * dx, s * dy)) break;
      last_inside = s;
    }
    return last_inside;
  };
  double min_x = -axis_extent(-1.0, 0.0);
  double max_x = axis_extent(1.0, 0.0);
  double min_y = -axis_extent(0.0, -1.0);
  double max_y = axis_extent(0.0, 1.0);
  if (min_x == 0.0 || max_x == 0.0 || min_y == 0.0 || max_y == 0.0)
    throw std::invalid_argument("crop rectification: the principal point is on the image border");

  // 2. Shrink the sides whose output pixels (sampled at the output resolution) fall outside.
  //    When a horizontal and a vertical side both fail, shrink only along the wider dimension:
  //    pulling in one pair of sides also pulls in the corners that made the other pair fail.
  constexpr double kShrink = 0.995;
  constexpr int kMaxIterations = 2000;  // 0.995^2000 ~ 4e-5: a crop that needs more is broken
  for (int iteration = 0;; ++iteration) {
    if (iteration == kMaxIterations)
      throw std::invalid_argument("crop rectification: no valid rectangle found");
    bool out_left = false, out_right = false, out_top = false, out_bottom = false;
    for (int i = 0; i < height; ++i) {
      const double y = min_y + (max_y - min_y) * i / (height - 1);
      out_left = out_left || !lands_inside(min_x, y);
      out_right = out_right || !lands_inside(max_x, y);
    }
    for (int i = 0; i < width; ++i) {
      const double x = min_x + (max_x - min_x) * i / (width - 1);
      out_top = out_top || !lands_inside(x, min_y);
      out_bottom = out_bottom || !lands_inside(x, max_y);
    }
    if (!(out_left || out_right || out_top || out_bottom)) break;
    if ((out_left || out_right) && (out_top || out_bottom)) {
      if (max_x - min_x > max_y - min_y)
        out_top = out_bottom = false;
      else
        out_left = out_right = false;
    }
    if (out_left) min_x *= kShrink;
    if (out_right) max_x *= kShrink;
    if (out_top) min_y *= kShrink;
    if (out_bottom) max_y *= kShrink;
  }
  return pinhole_spanning(min_x, max_x, min_y, max_y, width, height);
}

PinholeCamera make_full_pinhole(const CameraModel& input, int width, int height) {
  require_output_size(width, height);
  double min_x = 0.0, max_x = 0.0, min_y = 0.0, max_y = 0.0;
  const auto include = [&](double u, double v) {
    const std::optional<Eigen::Vector3d> ray = input.unproject(Eigen::Vector2d(u, v));
    if (!ray)
      throw std::invalid_argument(
          "full rectification: the input image border sees rays at 90 degrees or more (or "
          "beyond the model's valid range), which no pinhole can show; use crop");
    min_x = std::min(min_x, ray->x());
    max_x = std::max(max_x, ray->x());
    min_y = std::min(min_y, ray->y());
    max_y = std::max(max_y, ray->y());
  };
  const int w = input.width();
  const int h = input.height();
  for (int u = 0; u < w; ++u) {
    include(u, 0);
    include(u, h - 1);
  }
  for (int v = 0; v < h; ++v) {
    include(0, v);
    include(w - 1, v);
  }
  if (!(min_x < 0.0 && max_x > 0.0 && min_y < 0.0 && max_y > 0.0))
    throw std::invalid_argument("full rectification: the optical axis does not hit the image");
  return pinhole_spanning(min_x, max_x, min_y, max_y, width, height);
}

PinholeCamera make_output_pinhole(const CameraModel& input, const RectificationSpec& spec) {
  const bool default_size = spec.width == 0 && spec.height == 0;
  const int width = default_size ? input.width() : spec.width;
  const int height = default_size ? input.height() : spec.height;
  switch (spec.mode) {
    case RectificationMode::Crop: return make_crop_pinhole(input, width, height);
    case RectificationMode::Full: return make_full_pinhole(input, width, height);
    case RectificationMode::SameK:
      if (width != input.width() || height != input.height())
        throw std::invalid_argument("rectification 'same K' (DSO 'none') keeps the input size " +
                                    std::to_string(input.width()) + "x" +
                                    std::to_string(input.height()) + ", but the output is " +
                                    std::to_string(width) + "x" + std::to_string(height));
      return make_same_k_pinhole(input);
    case RectificationMode::Explicit:
      require_output_size(width, height);
      return PinholeCamera(width, height, spec.intrinsics);
  }
  throw std::invalid_argument("unknown rectification mode");
}

// ---------------------------------------------------------------------------------------------

Undistorter::Undistorter(const CameraModel& input, const RectificationSpec& spec)
    : Undistorter(input, make_output_pinhole(input, spec)) {}

Undistorter::Undistorter(const CameraModel& input, const PinholeCamera& output)
    : input_(input.clone()), output_(output) {
  const int w = output_.width();
  const int h = output_.height();
  identity_ = input.type() == CameraModelType::Pinhole && input.width() == w &&
              input.height() == h && input.intrinsics() == output_.intrinsics();

  map_x_.create(h, w, CV_32FC1);
  map_y_.create(h, w, CV_32FC1);
  valid_mask_.create(h, w, CV_8UC1);
  for (int v = 0; v < h; ++v) {
    auto* map_x_row = map_x_.ptr<float>(v);
    auto* map_y_row = map_y_.ptr<float>(v);
    auto* mask_row = valid_mask_.ptr<std::uint8_t>(v);
    for (int u = 0; u < w; ++u) {
      std::optional<Eigen::Vector2d> source;
      if (identity_) {
        source = Eigen::Vector2d(u, v);
      } else {
        const Eigen::Vector3d ray((u - output_.cx()) / output_.fx(),
                                  (v - output_.cy()) / output_.fy(), 1.0);
        source = input_->project(ray);
      }
      // Valid only where all four bilinear neighbours exist. A coordinate of exactly w-1 is
      // fine: its weight on the missing neighbour w is zero, also after OpenCV's fixed-point
      // rounding (to 1/32 px), which cannot round a value <= w-1 past w-1.
      if (source && input_->contains(*source)) {
        map_x_row[u] = static_cast<float>(source->x());
        map_y_row[u] = static_cast<float>(source->y());
        mask_row[u] = 255;
      } else {
        // -1 with zero fractional part puts the full bilinear weight on the constant border (0).
        map_x_row[u] = -1.0f;
        map_y_row[u] = -1.0f;
        mask_row[u] = 0;
      }
    }
  }
  cv::convertMaps(map_x_, map_y_, fixed_map_xy_, fixed_map_frac_, CV_16SC2, false);
}

double Undistorter::valid_fraction() const {
  return static_cast<double>(cv::countNonZero(valid_mask_)) / static_cast<double>(valid_mask_.total());
}

cv::Mat Undistorter::undistort(const cv::Mat& image) const {
  if (image.type() != CV_8UC1 && image.type() != CV_16UC1)
    throw std::invalid_argument("undistort: expected an 8- or 16-bit single-channel image");
  if (image.cols != input_->width() || image.rows != input_->height())
    throw std::invalid_argument("undistort: image is " + std::to_string(image.cols) + "x" +
                                std::to_string(image.rows) + " but the camera model is " +
                                std::to_string(input_->width()) + "x" +
                                std::to_string(input_->height()));
  if (identity_) return image.clone();
  cv::Mat output;
  cv::remap(image, output, fixed_map_xy_, fixed_map_frac_, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  return output;
}

Frame Undistorter::undistort(const Frame& frame) const {
  Frame output = frame;  // all metadata; the image is replaced below, never shared
  output.image = undistort(frame.image);
  return output;
}

}  // namespace nirslam
