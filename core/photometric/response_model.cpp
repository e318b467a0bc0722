#include "nirslam/photometric/response_model.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {

namespace {

// Legendre polynomial P_n(t) and its derivative, n = 0..3.
double legendre(int n, double t) {
  switch (n) {
    case 0: return 1.0;
    case 1: return t;
    case 2: return 0.5 * (3.0 * t * t - 1.0);
    default: return 0.5 * (5.0 * t * t - 3.0) * t;
  }
}
double legendre_derivative(int n, double t) {
  switch (n) {
    case 0: return 0.0;
    case 1: return 1.0;
    case 2: return 3.0 * t;
    default: return 0.5 * (15.0 * t * t - 3.0);
  }
}

// f as a function of u = sqrt(X), and df/du.
double f_of_u(const Eigen::Vector4d& c, double u) {
  Eigen::Vector4d h, dh_du;
  response_basis_in_sqrt_irradiance(u, h, dh_du);
  return u + c.dot(h);
}
double df_du(const Eigen::Vector4d& c, double u) {
  Eigen::Vector4d h, dh_du;
  response_basis_in_sqrt_irradiance(u, h, dh_du);
  return 1.0 + c.dot(dh_du);
}

[[noreturn]] void throw_write_error(const std::filesystem::path& file, const char* what, int error) {
  throw std::runtime_error(file.string() + ": " + what + " (" +
                           (error ? std::strerror(error) : "stream error") + ")");
}

}  // namespace

void response_basis_in_sqrt_irradiance(double u, Eigen::Vector4d& h, Eigen::Vector4d& dh_du) {
  const double t = 2.0 * u - 1.0;
  const double w = u * (1.0 - u);
  const double dw_du = 1.0 - 2.0 * u;
  for (int k = 0; k < 4; ++k) {
    const double p = legendre(k, t);
    h[k] = w * p;
    dh_du[k] = dw_du * p + w * 2.0 * legendre_derivative(k, t);
  }
}

std::string_view to_string(ResponsePreset preset) {
  switch (preset) {
    case ResponsePreset::Linear: return "linear";
    case ResponsePreset::Gamma: return "gamma";
    case ResponsePreset::Log: return "log";
    case ResponsePreset::Filmic: return "filmic";
  }
  return "unknown";
}

std::optional<ResponsePreset> parse_response_preset(std::string_view name) {
  const std::string key = lowercase(name);
  for (ResponsePreset p : {ResponsePreset::Linear, ResponsePreset::Gamma, ResponsePreset::Log,
                           ResponsePreset::Filmic})
    if (key == to_string(p)) return p;
  return std::nullopt;
}

ResponseModel ResponseModel::from_preset(ResponsePreset preset) {
  // Least-squares fits of the references (response_preset_reference) on 2 x 2000 samples uniform
  // in X and in sqrt(X). Largest deviation from the reference: gamma 0.68, log 1.32,
  // filmic 0.12 grey levels (of 255); linear is exact.
  switch (preset) {
    case ResponsePreset::Linear: return ResponseModel(Eigen::Vector4d(-1.0, 0.0, 0.0, 0.0));
    case ResponsePreset::Gamma:
      return ResponseModel(Eigen::Vector4d(0.151006714406475, -0.0966356334788762,
                                           0.0452657402807644, -0.0247195112670714));
    case ResponsePreset::Log:
      return ResponseModel(Eigen::Vector4d(0.176329232701220, 0.480033883452790,
                                           -0.375542812107450, 0.195220046404459));
    case ResponsePreset::Filmic:
      return ResponseModel(Eigen::Vector4d(0.150025084467470, 0.519445385731002,
                                           -0.0379643411858523, 0.00592077901189917));
  }
  throw std::invalid_argument("unknown response preset");
}

double response_preset_reference(ResponsePreset preset, double X) {
  X = std::clamp(X, 0.0, 1.0);
  switch (preset) {
    case ResponsePreset::Linear: return X;
    case ResponsePreset::Gamma: return std::pow(X, 1.0 / 2.2);
    case ResponsePreset::Log: return std::log1p(20.0 * X) / std::log(21.0);
    case ResponsePreset::Filmic: {
      // A smoothstep S-curve blended into gamma 2.2: toe-less but with a mid-tone contrast boost
      // and a soft shoulder.
      const double g = std::pow(X, 1.0 / 2.2);
      return 0.4 * g + 0.6 * g * g * (3.0 - 2.0 * g);
    }
  }
  return X;
}

double ResponseModel::operator()(double X) const {
  return f_of_u(c_, std::sqrt(std::clamp(X, 0.0, 1.0)));
}

double ResponseModel::derivative(double X) const {
  const double u = std::sqrt(std::clamp(X, 0.0, 1.0));
  const double slope_u = df_du(c_, u);
  if (u == 0.0) {
    if (slope_u != 0.0) return std::numeric_limits<double>::infinity();
    constexpr double kSmall = 1e-6;  // df/du vanishes at 0: the slope tends to f''(0) / 2
    return df_du(c_, kSmall) / (2.0 * kSmall);
  }
  return slope_u / (2.0 * u);
}

double ResponseModel::basis(int k, double X) {
  if (k < 0 || k > kCoefficientCount) throw std::out_of_range("response basis index must be 0..4");
  const double u = std::sqrt(std::clamp(X, 0.0, 1.0));
  if (k == 0) return u;
  return u * (1.0 - u) * legendre(k - 1, 2.0 * u - 1.0);
}

double ResponseModel::inverse(double y) const {
  y = std::clamp(y, 0.0, 1.0);
  double lo = 0.0, hi = 1.0;  // in u
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f_of_u(c_, mid) < y ? lo : hi) = mid;
  }
  const double u = 0.5 * (lo + hi);
  return u * u;
}

bool ResponseModel::is_monotonic(int samples) const {
  double previous = f_of_u(c_, 0.0);
  for (int i = 1; i <= samples; ++i) {
    const double value = f_of_u(c_, static_cast<double>(i) / samples);
    if (!(value > previous)) return false;
    previous = value;
  }
  return true;
}

std::vector<double> ResponseModel::inverse_table(int levels) const {
  if (levels < 2) throw std::invalid_argument("inverse response table needs at least 2 levels");
  std::vector<double> table(static_cast<std::size_t>(levels));
  const double top = levels - 1;
  for (int i = 0; i < levels; ++i) table[static_cast<std::size_t>(i)] = top * inverse(i / top);
  return table;
}

// ---------------------------------------------------------------------------------------------

double VignetteModel::radius(double col, double row, int width, int height) {
  const double cx = 0.5 * (width - 1), cy = 0.5 * (height - 1);
  const double half_diagonal = std::hypot(cx, cy);
  return half_diagonal > 0.0 ? std::hypot(col - cx, row - cy) / half_diagonal : 0.0;
}

cv::Mat VignetteModel::render(int width, int height) const {
  // V is a polynomial in r^2: no square roots per pixel (the corrected frames re-render V at
  // every small step of the model they follow).
  cv::Mat map(height, width, CV_32FC1);
  const double cx = 0.5 * (width - 1), cy = 0.5 * (height - 1);
  const double half_diagonal_sq = cx * cx + cy * cy;
  const double to_r2 = half_diagonal_sq > 0.0 ? 1.0 / half_diagonal_sq : 0.0;
  for (int y = 0; y < height; ++y) {
    float* row = map.ptr<float>(y);
    const double dy2 = (y - cy) * (y - cy);
    for (int x = 0; x < width; ++x) {
      const double r2 = ((x - cx) * (x - cx) + dy2) * to_r2;
      row[x] = static_cast<float>(1.0 + r2 * (v[0] + r2 * (v[1] + r2 * v[2])));
    }
  }
  return map;
}

bool VignetteModel::is_plausible(int samples) const {
  double previous = (*this)(0.0);
  for (int i = 1; i <= samples; ++i) {
    const double value = (*this)(static_cast<double>(i) / samples);
    if (!(value > 0.0) || value > previous + 1e-12) return false;
    previous = value;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

void write_pcalib(const std::filesystem::path& file, const std::vector<double>& inverse_response) {
  std::ofstream out(file, std::ios::out | std::ios::trunc);
  if (!out) throw_write_error(file, "cannot create", errno);
  out.precision(9);
  for (std::size_t i = 0; i < inverse_response.size(); ++i)
    out << (i ? " " : "") << inverse_response[i];
  out << '\n' << std::flush;
  if (!out) throw_write_error(file, "cannot write", errno);
  out.close();
  if (!out) throw_write_error(file, "cannot write", errno);
}

std::vector<double> read_pcalib(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file, std::filesystem::exists(file) ? "cannot open" : "file is missing");
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    const auto first = text.find_first_not_of(" \t\r");
    if (first != std::string::npos && text[first] != '#') break;
    text.clear();
  }
  if (text.empty()) throw InputError(file, "holds no inverse response values");
  std::istringstream stream(text);
  std::vector<double> values;
  for (std::string token; stream >> token;) {
    double value = 0.0;
    std::string_view view(token);
    if (!view.empty() && view.front() == '+') view.remove_prefix(1);
    const auto [end, error] = std::from_chars(view.data(), view.data() + view.size(), value);
    if (error != std::errc() || end != view.data() + view.size() || !std::isfinite(value))
      throw InputError(file, number, "'" + token + "' is not a number");
    values.push_back(value);
  }
  if (values.size() < 256)
    throw InputError(file, number,
                     "expected at least 256 inverse response values, got " + std::to_string(values.size()));
  for (std::size_t i = 1; i < values.size(); ++i)
    if (!(values[i] > values[i - 1]))
      throw InputError(file, number,
                       "the inverse response must increase strictly; value " + std::to_string(i) +
                           " does not");
  return values;
}

void write_vignette_png(const std::filesystem::path& file, const cv::Mat& vignette) {
  if (vignette.empty() || vignette.type() != CV_32FC1)
    throw std::invalid_argument("write_vignette_png: expected a non-empty CV_32FC1 map");
  double max_value = 0.0;
  cv::minMaxLoc(vignette, nullptr, &max_value);
  if (!(max_value > 0.0)) throw std::invalid_argument("write_vignette_png: the map has no positive value");
  cv::Mat image;
  vignette.convertTo(image, CV_16UC1, 65535.0 / max_value);
  write_image(file, image);
}

cv::Mat read_vignette_png(const std::filesystem::path& file) {
  if (!std::filesystem::exists(file)) throw InputError(file, "file is missing");
  const cv::Mat image = read_image(file);
  if (image.channels() != 1) throw InputError(file, "the vignette image must be grey, not colour");
  if (image.depth() != CV_8U && image.depth() != CV_16U)
    throw InputError(file, "the vignette image must be 8- or 16-bit");
  double max_value = 0.0;
  cv::minMaxLoc(image, nullptr, &max_value);
  if (!(max_value > 0.0)) throw InputError(file, "the vignette image is all zero");
  cv::Mat map;
  image.convertTo(map, CV_32FC1, 1.0 / max_value);
  return map;
}

}  // namespace nirslam
