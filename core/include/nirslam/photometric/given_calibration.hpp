#pragma once

// A photometric calibration given from files instead of estimated online: DSO's pcalib.txt and
// vignette.png, as TUM monoVO datasets ship them and `nirslam calibrate` writes them. With it
// the calibrated modes run as DSO does with those files: every frame corrected to G(I)/V, the
// source's exposures handed on, the model held (no back end).
//
// nirslam's model is parametric (response_model.hpp: f with four coefficients, V a polynomial
// in r^2), so the files are fitted by linear least squares and the fit's error is reported; a
// file the model cannot represent within the limits below is an error naming it, never a
// silently different correction.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/photometric/response_model.hpp"

namespace nirslam {

struct ResponseFit {
  ResponseModel response;
  double rms_grey = 0.0;  // |G_fit - G_given| over the table, grey levels of G (0..255 scale)
  double max_grey = 0.0;
};

// The response whose inverse is closest to `inverse_response` (pcalib.txt's G[0..n-1], any
// scale: normalised so that G[n-1] is full scale), by least squares on f(G[i] / G[n-1]) =
// i / (n - 1) in the basis of response_model.hpp; when that dips near black (curves close to
// linear there), again with the slope at black held at 0. The fit may still come out
// non-monotonic for tables the basis cannot follow; ResponseFit::response.is_monotonic() says.
ResponseFit fit_response_to_inverse_table(const std::vector<double>& inverse_response);

struct VignetteFit {
  VignetteModel vignette;
  double rms = 0.0;  // |V_fit - V_given| over the image, both scaled to their maximum
  double max = 0.0;
};

// V(r) = 1 + v1 r^2 + v2 r^4 + v3 r^6 closest to `vignette` (CV_32FC1, any scale) up to a
// factor, by linear least squares over every pixel on a 4-pixel grid.
VignetteFit fit_vignette_to_image(const cv::Mat& vignette);

// Which part of a given calibration is held; the rest is estimated online. A response alone
// (pcalib.txt) fixes the gamma and scale ambiguity; a vignette alone (vignette.png, e.g. the
// lens's from a calibration with the lamp off) leaves the response to the back end.
enum class GivenCalibrationParts { Both, Response, Vignette };

const char* to_string(GivenCalibrationParts parts);
// "both", "response" or "vignette"; std::nullopt for anything else.
std::optional<GivenCalibrationParts> given_calibration_parts_from_string(const std::string& text);

struct GivenPhotometricCalibration {
  GivenCalibrationParts parts = GivenCalibrationParts::Both;
  ResponseModel response;  // the gamma preset when the response is not given
  VignetteModel vignette;  // V = 1 when the folder has no vignette.png
  std::optional<ResponseFit> response_fit;
  std::optional<VignetteFit> vignette_fit;
  std::filesystem::path folder;
  std::string response_description;  // the file and its fit error; empty when not read
  std::string vignette_description;
  std::string description;  // both, for the log and the Photometric status
};

// Limits beyond which a given file is refused: the correction would differ from what the file
// says by more than the online calibration's own targets (README "Photometric calibration
// accuracy": 2 grey levels, a vignette within 0.005 in the mean).
inline constexpr double kGivenResponseMaxRmsGrey = 2.0;
inline constexpr double kGivenVignetteMaxRms = 0.01;

// Reads `folder`/pcalib.txt (required unless only the vignette is given) and `folder`/vignette.png
// (optional for Both, required for Vignette, not read for Response) and fits the model to them.
// Throws InputError naming the file: missing or malformed files, a vignette whose size is not
// width x height (not checked when they are 0: the camera is not known), a fit beyond the limits
// above or a response that does not increase.
GivenPhotometricCalibration read_given_calibration(const std::filesystem::path& folder, int width, int height,
                                                   GivenCalibrationParts parts = GivenCalibrationParts::Both);

}  // namespace nirslam
