#pragma once

// The trajectory error heat map (top view), drawn with OpenCV only: the ground truth as a dark
// grey line, the aligned estimate coloured by its per-pose ATE (turbo colour map, 0 m blue to the
// largest error red) with a colour bar in metres, axes with tick labels in metres, equal aspect,
// and a title. The view plane is spanned by the two world axes along which the ground truth
// extends most (x-y for a ground vehicle with z up, x-z for a camera frame with y down).

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace nirslam {

struct EvaluationResult;

struct ErrorPlotOptions {
  int width = 1200;   // pixels
  int height = 900;
  std::string title;  // empty: no title line
  std::string subtitle;
  // Upper end of the colour scale; by default the largest error (the lower end is always 0 m).
  std::optional<double> color_max_m;
};

// Data for the plot: `estimate` and `errors_m` have one entry per pose; `ground_truth` is the whole
// reference path (any length). Throws std::invalid_argument for mismatched lengths, an empty
// estimate, or a size under 320x240.
cv::Mat render_error_heat_map(const std::vector<Eigen::Vector3d>& ground_truth,
                              const std::vector<Eigen::Vector3d>& estimate, const std::vector<double>& errors_m,
                              const ErrorPlotOptions& options = {});

// The same for an evaluation: the ground-truth path, the aligned estimate, and a title naming the
// ATE RMSE and the alignment (options.title, when set, replaces it).
cv::Mat render_evaluation_heat_map(const std::vector<Eigen::Vector3d>& ground_truth, const EvaluationResult& result,
                                   ErrorPlotOptions options = {});

// Writes an image as PNG; throws InputError naming the file when it cannot.
void write_png(const std::filesystem::path& file, const cv::Mat& image);

}  // namespace nirslam
