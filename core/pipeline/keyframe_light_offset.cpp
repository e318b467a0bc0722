#include "nirslam/pipeline/keyframe_light_offset.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

namespace nirslam {
namespace {

// Bilinear lookup; NaN outside the image or where a corner is NaN (no light there).
float sample(const cv::Mat& image, const Eigen::Vector2d& pixel) {
  const double x = pixel.x(), y = pixel.y();
  if (!(x >= 0.0 && y >= 0.0 && x < image.cols - 1 && y < image.rows - 1)) return std::numeric_limits<float>::quiet_NaN();
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* row0 = image.ptr<float>(y0) + x0;
  const float* row1 = image.ptr<float>(y0 + 1) + x0;
  return (1 - fy) * ((1 - fx) * row0[0] + fx * row0[1]) + fy * ((1 - fx) * row1[0] + fx * row1[1]);
}

}  // namespace

KeyframeLightOffset::KeyframeLightOffset(const PinholeCamera& camera, KeyframeLightOffsetOptions options)
    : camera_(camera), options_(std::move(options)), normals_(camera, options_.normals) {
  set_beam_exponent(options_.beam_exponent);
}

void KeyframeLightOffset::set_beam_exponent(double beam_exponent) {
  // Small changes (each back-end update moves the halo a little) keep what is stored.
  if (beam_set_ && std::abs(beam_exponent - options_.beam_exponent) < 0.1) return;
  beam_set_ = true;
  views_.clear();
  options_.beam_exponent = beam_exponent;
  options_.estimator.beam_exponent = beam_exponent;
  beam_by_pixel_.release();
  if (options_.beam_exponent > 0.0) {
    beam_by_pixel_.create(camera_.height(), camera_.width(), CV_32FC1);
    for (int y = 0; y < camera_.height(); ++y)
      for (int x = 0; x < camera_.width(); ++x) {
        const auto ray = camera_.unproject(Eigen::Vector2d(x, y));
        const double cos_alpha = ray ? ray->normalized().z() : 0.0;
        beam_by_pixel_.at<float>(y, x) = static_cast<float>(cos_alpha > 0.0 ? std::pow(cos_alpha, options_.beam_exponent) : 0.0);
      }
  }
}

void KeyframeLightOffset::clear() {
  views_.clear();
  normals_.clear();
  segment_ = -1;
}

void KeyframeLightOffset::add_keyframe(int segment, const SE3& T_world_cam, const cv::Mat& corrected,
                                       double exposure_times_power) {
  if (segment != segment_) clear();
  segment_ = segment;
  if (!(exposure_times_power > 0.0) || corrected.empty()) return;
  View view;
  view.T_cam_world = T_world_cam.inverse();
  cv::Mat irradiance;
  corrected.convertTo(irradiance, CV_32F, 1.0 / exposure_times_power);
  if (!beam_by_pixel_.empty()) irradiance = irradiance.mul(beam_by_pixel_);  // G/H * B = G/V
  const double sigma = options_.blur_sigma_px * camera_.width() / 640.0;
  cv::GaussianBlur(irradiance, irradiance, cv::Size(), sigma);
  view.log_irradiance.create(irradiance.size(), CV_32FC1);
  // Below a grey level of about 1 (at this exposure) there is no usable light: NaN, left out.
  const float floor = static_cast<float>(1.0 / exposure_times_power);
  for (int y = 0; y < irradiance.rows; ++y) {
    const float* in = irradiance.ptr<float>(y);
    float* out = view.log_irradiance.ptr<float>(y);
    for (int x = 0; x < irradiance.cols; ++x)
      out[x] = in[x] > floor ? std::log(in[x]) : std::numeric_limits<float>::quiet_NaN();
  }
  views_.push_back(std::move(view));
  while (views_.size() > options_.keyframes) views_.pop_front();
}

LightOffsetEstimate KeyframeLightOffset::estimate(std::span<const Eigen::Vector3d> points_world,
                                                  const Eigen::Vector3d& start) {
  LightOffsetEstimator estimator(options_.estimator);
  if (views_.empty()) return estimator.estimate(start);
  // Normals from the newest keyframe's view of the points (the plane through a point's image
  // neighbours), carried to the other keyframes by their rotations.
  const View& newest = views_.back();
  const SE3 T_world_newest = newest.T_cam_world.inverse();
  normals_.build(points_world, T_world_newest, start);
  const Eigen::Matrix3d R_world_newest = T_world_newest.rotation_matrix();
  int in_view = 0, with_normal = 0, used = 0;
  for (const Eigen::Vector3d& p_world : points_world) {
    const auto pixel = camera_.project(newest.T_cam_world * p_world);
    if (!pixel) continue;
    ++in_view;
    const auto geometry = normals_.light_geometry(*pixel);
    std::optional<Eigen::Vector3d> normal_world;
    if (geometry && geometry->normal_cam) normal_world = R_world_newest * *geometry->normal_cam;
    // Without a normal, cos(theta) changes between views unmodelled, by as much as the offset's
    // own effect: such points would bias L, so they are left out.
    if (!normal_world) continue;
    ++with_normal;
    seen_.clear();
    for (const View& view : views_) {
      LampObservation o;
      o.p_cam = view.T_cam_world * p_world;
      const auto at = camera_.project(o.p_cam);
      if (!at) continue;
      const float l = sample(view.log_irradiance, *at);
      if (!std::isfinite(l)) continue;
      o.log_irradiance = l;
      o.normal_cam = view.T_cam_world.rotation_matrix() * *normal_world;
      seen_.push_back(o);
    }
    if (static_cast<int>(seen_.size()) >= options_.min_views) {
      ++used;
      estimator.add_point(seen_);
    }
  }
  LightOffsetEstimate e = estimator.estimate(start);
  if (!e.determined)
    e.reason += fmt::format(" ({} of {} window points in view have a surface normal from a plane through their "
                            "neighbours, {} of them seen by {} keyframes)",
                            with_normal, in_view, used, options_.min_views);
  return e;
}

}  // namespace nirslam
