#pragma once
// The plots of a session report, drawn with OpenCV only (BGR, white background): a generic line
// chart and the session's figures built on it. Each throws std::invalid_argument for data it
// cannot draw (no points, mismatched lengths).

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "nirslam/session/session_format.hpp"

namespace nirslam {

struct PlotSeries {
  std::vector<double> x;
  std::vector<double> y;
  cv::Scalar colour;  // BGR
  std::string label;  // in the legend; empty: no legend entry
};

struct LinePlotOptions {
  int width = 1000;
  int height = 420;
  std::string title;
  std::string x_label;
  std::string y_label;
};

// Axes with tick labels fitted to the data, one polyline per series, a legend.
cv::Mat render_line_plot(const std::vector<PlotSeries>& series, const LinePlotOptions& options);

// Entropy in bits over the session's time (from the first frame), from the journal.
cv::Mat render_entropy_plot(const std::vector<JournalEntry>& journal);
// Exposure (ms) as the camera reported it, and the calibration's estimate when given (scaled to
// the reported one at the first frame both know; `estimated` pairs timestamp and exposure).
cv::Mat render_exposure_plot(const std::vector<JournalEntry>& journal,
                             const std::vector<std::pair<double, double>>& estimated);
// The estimated inverse response G^-1 (pcalib.txt) against the linear one, beside the vignette map
// (vignette.png as read, 0..1, turbo colours).
cv::Mat render_photometric_plot(const std::vector<double>& inverse_response, const cv::Mat& vignette);
// Top view of the estimated path (each segment its own colour) and the ground truth when given,
// equal aspect, on the two axes along which the paths extend most.
cv::Mat render_trajectory_top_view(const std::vector<std::vector<Eigen::Vector3d>>& segments,
                                   const std::vector<Eigen::Vector3d>& ground_truth);

}  // namespace nirslam
