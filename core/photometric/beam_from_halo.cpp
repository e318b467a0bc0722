#include "nirslam/photometric/beam_from_halo.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <opencv2/core.hpp>

namespace nirslam {
namespace {

void check_sizes(const cv::Mat& halo, const cv::Mat& lens_vignette) {
  if (halo.size() != lens_vignette.size())
    throw std::invalid_argument(fmt::format("the halo factor is {}x{} but the lens vignette is {}x{}", halo.cols,
                                            halo.rows, lens_vignette.cols, lens_vignette.rows));
}

cv::Mat as_float(const cv::Mat& image) {
  cv::Mat out;
  image.convertTo(out, CV_32F);
  return out;
}

}  // namespace

BeamFit fit_beam_from_halo(const cv::Mat& halo_in, const cv::Mat& vignette_in, const CameraModel& camera, int step,
                           double min_value) {
  check_sizes(halo_in, vignette_in);
  if (halo_in.cols != camera.width() || halo_in.rows != camera.height())
    throw std::invalid_argument(fmt::format("the halo factor is {}x{} but the camera is {}x{}", halo_in.cols,
                                            halo_in.rows, camera.width(), camera.height()));
  const cv::Mat halo = as_float(halo_in), vignette = as_float(vignette_in);
  double halo_max = 0.0, vignette_max = 0.0;
  cv::minMaxLoc(halo, nullptr, &halo_max);
  cv::minMaxLoc(vignette, nullptr, &vignette_max);
  BeamFit fit;
  if (!(halo_max > 0.0) || !(vignette_max > 0.0)) {
    fit.reason = "an image is black";
    return fit;
  }
  // Samples (log cos(alpha), log(H / V)) in one pass; then linear least squares in
  // (log_scale, m): log(H / V) = log_scale + m log cos(alpha).
  std::vector<Eigen::Vector2d> samples;
  samples.reserve(static_cast<std::size_t>((halo.rows / step + 1) * (halo.cols / step + 1)));
  double min_cos = 1.0;
  for (int y = step / 2; y < halo.rows; y += step)
    for (int x = step / 2; x < halo.cols; x += step) {
      const double h = halo.at<float>(y, x), v = vignette.at<float>(y, x);
      if (!(h > min_value * halo_max) || !(v > min_value * vignette_max)) continue;
      const auto ray = camera.unproject(Eigen::Vector2d(x, y));
      if (!ray) continue;
      const double cos_alpha = ray->normalized().z();
      if (!(cos_alpha > 0.0)) continue;
      samples.emplace_back(std::log(cos_alpha), std::log(h / v));
      min_cos = std::min(min_cos, cos_alpha);
    }
  fit.samples = static_cast<int>(samples.size());
  fit.max_alpha_deg = std::acos(min_cos) * 180.0 / std::numbers::pi;
  // Below ~10 degrees cos(alpha)^m hardly differs from 1: nothing to fit.
  if (fit.samples < 50 || fit.max_alpha_deg < 10.0) {
    fit.reason = fmt::format("{} usable pixels reaching {:.1f} degrees off the axis: too few or too central",
                             fit.samples, fit.max_alpha_deg);
    return fit;
  }
  Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& sample : samples) {
    const Eigen::Vector2d a(1.0, sample.x());
    normal += a * a.transpose();
    rhs += a * sample.y();
  }
  const Eigen::Vector2d solution = normal.ldlt().solve(rhs);
  fit.log_scale = solution[0];
  fit.beam_exponent = solution[1];
  double sum_r2 = 0.0;
  for (const Eigen::Vector2d& sample : samples) {
    const double r = sample.y() - fit.log_scale - fit.beam_exponent * sample.x();
    sum_r2 += r * r;
  }
  fit.rms_log = std::sqrt(sum_r2 / fit.samples);
  if (!(fit.beam_exponent > 0.0)) {
    fit.reason = fmt::format("the halo factor is not darker than the lens vignetting off the axis (m = {:.2f}): no "
                             "beam, or the lamp was off",
                             fit.beam_exponent);
    return fit;
  }
  fit.half_angle_deg = std::acos(std::pow(0.5, 1.0 / fit.beam_exponent)) * 180.0 / std::numbers::pi;
  fit.ok = true;
  return fit;
}

cv::Mat halo_with_beam(const cv::Mat& lens_vignette, const CameraModel& camera, double beam_exponent) {
  if (lens_vignette.cols != camera.width() || lens_vignette.rows != camera.height())
    throw std::invalid_argument(fmt::format("the lens vignette is {}x{} but the camera is {}x{}", lens_vignette.cols,
                                            lens_vignette.rows, camera.width(), camera.height()));
  cv::Mat halo = as_float(lens_vignette);
  for (int y = 0; y < halo.rows; ++y) {
    float* row = halo.ptr<float>(y);
    for (int x = 0; x < halo.cols; ++x) {
      const auto ray = camera.unproject(Eigen::Vector2d(x, y));
      if (!ray) continue;
      const double cos_alpha = ray->normalized().z();
      if (cos_alpha > 0.0) row[x] *= static_cast<float>(std::pow(cos_alpha, beam_exponent));
    }
  }
  return halo;
}

cv::Mat beam_pattern(const cv::Mat& halo, const cv::Mat& lens_vignette) {
  check_sizes(halo, lens_vignette);
  cv::Mat h = as_float(halo), v = as_float(lens_vignette), beam;
  cv::divide(h, cv::max(v, 1e-6), beam);
  double max_value = 0.0;
  cv::minMaxLoc(beam, nullptr, &max_value);
  if (max_value > 0.0) beam /= max_value;
  return beam;
}

}  // namespace nirslam
