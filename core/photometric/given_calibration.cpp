#include "nirslam/photometric/given_calibration.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "nirslam/common/error.hpp"

namespace nirslam {

ResponseFit fit_response_to_inverse_table(const std::vector<double>& inverse_response) {
  const std::size_t n = inverse_response.size();
  ResponseFit fit;
  if (n < 2 || !(inverse_response.back() > 0.0)) return fit;
  const double full_scale = inverse_response.back();
  // f(X) = u + c . h(u) with u = sqrt(X) is linear in c: rows h(u_i), right side y_i - u_i.
  Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
  Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
  Eigen::Vector4d h, dh;
  for (std::size_t i = 0; i < n; ++i) {
    const double X = std::clamp(inverse_response[i] / full_scale, 0.0, 1.0);
    const double u = std::sqrt(X);
    const double y = static_cast<double>(i) / static_cast<double>(n - 1);
    response_basis_in_sqrt_irradiance(u, h, dh);
    normal.noalias() += h * h.transpose();
    rhs += (y - u) * h;
  }
  fit.response = ResponseModel(normal.ldlt().solve(rhs));
  if (!fit.response.is_monotonic()) {
    // A curve close to linear near black (f ~ X = u^2, slope 0 in u at u = 0) sits on the edge of
    // monotonicity in this basis, and the free fit dips below 0 there (DSO's pcalib.txt of the
    // EuRoC cameras does). Refit with the slope at black held at 0: 1 + c . dh(0) = 0, dh(0) =
    // (1, -1, 1, -1), by least squares with that equality (the KKT system).
    const Eigen::Vector4d slope_at_black(1.0, -1.0, 1.0, -1.0);
    Eigen::Matrix<double, 5, 5> kkt = Eigen::Matrix<double, 5, 5>::Zero();
    kkt.topLeftCorner<4, 4>() = normal;
    kkt.block<4, 1>(0, 4) = slope_at_black;
    kkt.block<1, 4>(4, 0) = slope_at_black.transpose();
    Eigen::Matrix<double, 5, 1> right;
    right << rhs, -1.0;
    fit.response = ResponseModel(kkt.fullPivLu().solve(right).head<4>());
    if (!fit.response.is_monotonic()) return fit;
  }
  // The error where the correction uses it: G, on the table's own grey levels.
  const std::vector<double> fitted = fit.response.inverse_table(static_cast<int>(n));
  double sum_squares = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double given = inverse_response[i] / full_scale * static_cast<double>(n - 1);
    const double miss = std::abs(fitted[i] - given) * 255.0 / static_cast<double>(n - 1);
    sum_squares += miss * miss;
    fit.max_grey = std::max(fit.max_grey, miss);
  }
  fit.rms_grey = std::sqrt(sum_squares / static_cast<double>(n));
  return fit;
}

VignetteFit fit_vignette_to_image(const cv::Mat& vignette) {
  constexpr int kStep = 4;
  VignetteFit fit;
  const int width = vignette.cols, height = vignette.rows;
  // V_given = k (1 + v1 r^2 + v2 r^4 + v3 r^6) is linear in p = k (1, v1, v2, v3).
  Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
  Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
  for (int row = 0; row < height; row += kStep) {
    const float* given = vignette.ptr<float>(row);
    for (int col = 0; col < width; col += kStep) {
      const double r2 = std::pow(VignetteModel::radius(col, row, width, height), 2);
      const Eigen::Vector4d powers(1.0, r2, r2 * r2, r2 * r2 * r2);
      normal.noalias() += powers * powers.transpose();
      rhs += static_cast<double>(given[col]) * powers;
    }
  }
  const Eigen::Vector4d p = normal.ldlt().solve(rhs);
  if (!(std::abs(p[0]) > 1e-12)) return fit;
  fit.vignette.v = p.tail<3>() / p[0];
  double fitted_max = 0.0, given_max = 0.0;
  for (int j = 0; j <= 1000; ++j) fitted_max = std::max(fitted_max, fit.vignette(j / 1000.0));
  cv::minMaxLoc(vignette, nullptr, &given_max);
  if (!(fitted_max > 0.0) || !(given_max > 0.0)) return fit;
  double sum_squares = 0.0;
  int count = 0;
  for (int row = 0; row < height; row += kStep) {
    const float* given = vignette.ptr<float>(row);
    for (int col = 0; col < width; col += kStep) {
      const double miss = std::abs(fit.vignette(VignetteModel::radius(col, row, width, height)) / fitted_max -
                                   static_cast<double>(given[col]) / given_max);
      sum_squares += miss * miss;
      fit.max = std::max(fit.max, miss);
      ++count;
    }
  }
  fit.rms = std::sqrt(sum_squares / std::max(count, 1));
  return fit;
}

const char* to_string(GivenCalibrationParts parts) {
  switch (parts) {
    case GivenCalibrationParts::Both: return "both";
    case GivenCalibrationParts::Response: return "response";
    case GivenCalibrationParts::Vignette: return "vignette";
  }
  return "?";
}

std::optional<GivenCalibrationParts> given_calibration_parts_from_string(const std::string& text) {
  for (const GivenCalibrationParts parts :
       {GivenCalibrationParts::Both, GivenCalibrationParts::Response, GivenCalibrationParts::Vignette})
    if (text == to_string(parts)) return parts;
  return std::nullopt;
}

GivenPhotometricCalibration read_given_calibration(const std::filesystem::path& folder, int width, int height,
                                                   GivenCalibrationParts parts) {
  if (!std::filesystem::is_directory(folder))
    throw InputError(folder, "the given photometric calibration must be a folder holding pcalib.txt (and vignette.png)");
  GivenPhotometricCalibration given;
  given.parts = parts;
  given.folder = folder;
  given.response = ResponseModel::from_preset(ResponsePreset::Gamma);
  if (parts != GivenCalibrationParts::Vignette) {
    const std::filesystem::path pcalib = folder / "pcalib.txt";
    const ResponseFit fit = fit_response_to_inverse_table(read_pcalib(pcalib));
    if (!fit.response.is_monotonic())
      throw InputError(pcalib, "nirslam's response model cannot follow this inverse response (its fit does not increase)");
    if (fit.rms_grey > kGivenResponseMaxRmsGrey)
      throw InputError(pcalib, fmt::format("nirslam's response model follows this inverse response only to {:.2f} grey "
                                           "levels rms (max {:.1f}); more than {:.1f} would correct the frames "
                                           "differently from the file",
                                           fit.rms_grey, fit.max_grey, kGivenResponseMaxRmsGrey));
    given.response = fit.response;
    given.response_fit = fit;
    given.response_description =
        fmt::format("{} (fitted to {:.2f} grey levels rms, max {:.2f})", pcalib.string(), fit.rms_grey, fit.max_grey);
  }

  const std::filesystem::path vignette_png = folder / "vignette.png";
  if (parts != GivenCalibrationParts::Response) {
    if (!std::filesystem::exists(vignette_png)) {
      if (parts == GivenCalibrationParts::Vignette)
        throw InputError(vignette_png, "only the vignette is to be held from this folder, but it has no vignette.png");
      given.vignette_description = "no vignette.png: no vignetting";
    } else {
      const cv::Mat vignette = read_vignette_png(vignette_png);
      if (width > 0 && height > 0 && (vignette.cols != width || vignette.rows != height))
        throw InputError(vignette_png,
                         fmt::format("the vignette is {}x{}, the camera {}x{}", vignette.cols, vignette.rows, width, height));
      VignetteFit fit = fit_vignette_to_image(vignette);
      bool positive = true;
      for (int j = 0; j <= 1000; ++j) positive = positive && fit.vignette(j / 1000.0) > 0.0;
      if (!positive) throw InputError(vignette_png, "nirslam's vignette model fitted to this image is not positive everywhere");
      if (fit.rms > kGivenVignetteMaxRms)
        throw InputError(vignette_png, fmt::format("nirslam's radial vignette model follows this image only to {:.4f} rms "
                                                   "(max {:.3f}); more than {:.3f} would correct the frames differently "
                                                   "from the file",
                                                   fit.rms, fit.max, kGivenVignetteMaxRms));
      given.vignette = fit.vignette;
      given.vignette_description = fmt::format("{} (fitted to {:.4f} rms, max {:.4f})", vignette_png.string(), fit.rms, fit.max);
      given.vignette_fit = fit;
    }
  }
  given.description = given.response_description;
  if (!given.vignette_description.empty())
    given.description += (given.description.empty() ? "" : given.vignette_fit ? ", " : "; ") + given.vignette_description;
  return given;
}

}  // namespace nirslam
