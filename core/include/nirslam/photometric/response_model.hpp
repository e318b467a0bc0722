#pragma once

// The photometric model's two slowly changing parts, shared by the simulator (which renders with
// them) and the photometric calibration (which estimates them), and their DSO file formats.
//
//   I(x) = f(e * V(x) * L)          (DESIGN.md, "The photometric model")
//
// Response f: [0, 1] -> [0, 1], from the sensor's normalised exposure X (1 = saturation) to the
// normalised grey value (multiply by 255, or 65535 for 16-bit images). It has four coefficients
// c1..c4 on this basis (the "sqrt-Legendre" basis, defined here for nirslam):
//
//   u = sqrt(X),  t = 2u - 1,
//   f(X) = h0(X) + c1 h1(X) + c2 h2(X) + c3 h3(X) + c4 h4(X)
//   h0(X) = u                                       (the mean curve: a gamma 2.0 curve)
//   hk(X) = u (1 - u) P_{k-1}(t),  k = 1..4         (P_n: Legendre polynomials on [-1, 1])
//          P0 = 1, P1 = t, P2 = (3t^2 - 1)/2, P3 = (5t^3 - 3t)/2
//
// So f is a polynomial of degree 5 in sqrt(X) with f(0) = 0 and f(1) = 1 for every c, linear in c
// (as EMoR is, which keeps the Jacobians of a least-squares calibration simple). The sqrt makes
// gamma-like curves (slope growing without bound towards black) cheap to express: c = (-1, 0, 0, 0)
// is exactly the linear response f(X) = X, c = 0 is gamma 2.0, and the presets below fit a gamma
// 2.2 curve, a logarithmic wide-dynamic-range curve and a film-like S-curve with a toe to within
// a grey level or two (the presets ARE the curves their coefficients give; the references only
// motivated them, see response_preset_reference). Not every c gives a monotonic curve:
// is_monotonic() checks, and the calibration must keep its estimate monotonic.
//
// The inverse response G = f^-1 is kept as a table in grey-level units, as DSO's pcalib.txt holds
// it: G[i] = 255 * f^-1(i / 255) for i = 0..255 (also for 16-bit images, whose grey value g maps
// to the table position g / 257).
//
// Vignetting: V(r) = 1 + v1 r^2 + v2 r^4 + v3 r^6, r = distance of a pixel centre from the image
// centre ((w-1)/2, (h-1)/2) divided by the half-diagonal hypot((w-1)/2, (h-1)/2), so the corner
// pixels have r = 1. vignette.png stores V scaled to its maximum (DSO divides by the maximum).

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace nirslam {

enum class ResponsePreset {
  Linear,  // f(X) = X, exact (machine-vision cameras with gamma off)
  Gamma,   // close to X^(1/2.2), an sRGB-like display gamma
  Log,     // close to log(1 + 30 X) / log(31), a wide-dynamic-range sensor curve
  Filmic,  // an S-curve with a toe and a shoulder, like consumer camera tone curves
};

std::string_view to_string(ResponsePreset preset);
// Accepts the names to_string gives ("linear", "gamma", "log", "filmic"), any case.
std::optional<ResponsePreset> parse_response_preset(std::string_view name);

class ResponseModel {
public:
  static constexpr int kCoefficientCount = 4;

  // c = 0: the basis mean curve f(X) = sqrt(X).
  ResponseModel() = default;
  explicit ResponseModel(const Eigen::Vector4d& c) : c_(c) {}
  static ResponseModel from_preset(ResponsePreset preset);

  const Eigen::Vector4d& coefficients() const { return c_; }

  // f(X); X is clamped to [0, 1].
  double operator()(double X) const;
  // df/dX at X in (0, 1]; +inf at X = 0 unless 1 + c1 - c2 + c3 - c4 = 0.
  double derivative(double X) const;
  // The basis function h_k(X), k = 0 (the mean curve) .. 4.
  static double basis(int k, double X);
  // f^-1(y) for y in [0, 1] (clamped), by bisection on u = sqrt(X); requires a monotonic curve.
  double inverse(double y) const;
  // Whether f is strictly increasing on [0, 1], checked on `samples` points of u.
  bool is_monotonic(int samples = 4096) const;

  // The inverse response in grey-level units: G[i] = (levels - 1) f^-1(i / (levels - 1)).
  std::vector<double> inverse_table(int levels = 256) const;

private:
  Eigen::Vector4d c_ = Eigen::Vector4d::Zero();
};

// The basis in u = sqrt(X): h_k(u) = u (1 - u) P_{k-1}(2u - 1) for k = 1..4 (stored at k - 1),
// with P the Legendre polynomials, and dh_k/du; f(u) = u + c . h(u). Calibration works in u (or
// log X), where f stays smooth down to black.
void response_basis_in_sqrt_irradiance(double u, Eigen::Vector4d& h, Eigen::Vector4d& dh_du);

// The curve a preset was fitted to (for documentation and tests; the preset itself is its
// coefficients, not this curve).
double response_preset_reference(ResponsePreset preset, double X);

// ---------------------------------------------------------------------------------------------

struct VignetteModel {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();  // v1, v2, v3

  // V(r) with r normalised to the half-diagonal (1 at the corner pixels).
  double operator()(double r) const {
    const double r2 = r * r;
    return 1.0 + r2 * (v[0] + r2 * (v[1] + r2 * v[2]));
  }
  // r of pixel (col, row) in a width x height image.
  static double radius(double col, double row, int width, int height);
  // V at every pixel, CV_32FC1.
  cv::Mat render(int width, int height) const;
  // Whether V is positive and non-increasing on [0, 1] (a lens darkens towards the rim),
  // checked on `samples` radii.
  bool is_plausible(int samples = 1024) const;
};

// ---------------------------------------------------------------------------------------------
// DSO photometric calibration files.

// pcalib.txt: one line of the inverse response values G[0..n-1] (grey-level units, strictly
// increasing). Throws std::runtime_error naming the file when it cannot be written (full disk).
void write_pcalib(const std::filesystem::path& file, const std::vector<double>& inverse_response);
// Reads the first non-comment line's numbers. Throws InputError naming the file (and line) when
// the file is missing, has fewer than 256 numbers, a non-number, or values that do not increase.
std::vector<double> read_pcalib(const std::filesystem::path& file);

// vignette.png: V scaled so its maximum is 65535, 16-bit grey. Throws std::runtime_error naming
// the file when it cannot be written.
void write_vignette_png(const std::filesystem::path& file, const cv::Mat& vignette);
// Reads an 8- or 16-bit grey vignette image and returns it divided by its maximum, CV_32FC1.
// Throws InputError naming the file when it is missing, undecodable, colour or all zero.
cv::Mat read_vignette_png(const std::filesystem::path& file);

}  // namespace nirslam
