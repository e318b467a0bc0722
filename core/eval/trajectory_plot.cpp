#include "nirslam/eval/trajectory_plot.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/eval/evaluation.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam {

namespace {

const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kLabelColor(30, 30, 30);
const cv::Scalar kFrame(60, 60, 60);
const cv::Scalar kGridColor(228, 228, 228);
const cv::Scalar kGroundTruth(110, 110, 110);

// A "nice" step (1, 2 or 5 times a power of ten) that cuts `range` into about `count` parts.
double grid_step(double range, double count) {
  const double raw = range / count;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (raw <= m * power * (1.0 + 1e-9)) return m * power;
  return 10.0 * power;
}

int decimals_for(double step) { return std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9))); }

std::string fixed_decimals_label(double value, int decimals) {
  if (std::abs(value) < 1e-12) value = 0.0;  // no "-0.0"
  std::array<char, 48> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.*f", decimals, value);
  return buffer.data();
}

struct Fonts {
  double scale;       // layout factor relative to 1200 x 900
  double tick;        // font scales
  double label;
  double title;
  int thickness;
};

cv::Size text_size(const std::string& text, int face, double scale, int thickness) {
  int baseline = 0;
  return cv::getTextSize(text, face, scale, thickness, &baseline);
}

// Text with its left end at x and its baseline at y.
void put(cv::Mat& image, const std::string& text, cv::Point origin, double scale, int thickness,
         int face = cv::FONT_HERSHEY_SIMPLEX, const cv::Scalar& color = kLabelColor) {
  cv::putText(image, text, origin, face, scale, color, thickness, cv::LINE_AA);
}

// Text rotated a quarter turn counter-clockwise (read bottom to top), its left edge at x, centred on
// centre_y. Returns the width it takes.
int put_vertical(cv::Mat& image, const std::string& text, int x, int centre_y, double scale, int thickness, int pad) {
  const cv::Size size = text_size(text, cv::FONT_HERSHEY_SIMPLEX, scale, thickness);
  cv::Mat horizontal(size.height + 3 * pad, size.width + 2 * pad, CV_8UC3, kWhite);
  put(horizontal, text, {pad, size.height + pad}, scale, thickness);
  cv::Mat rotated;
  cv::rotate(horizontal, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  x = std::clamp(x, 0, image.cols - rotated.cols);
  const int y = std::clamp(centre_y - rotated.rows / 2, 0, image.rows - rotated.rows);
  rotated.copyTo(image(cv::Rect(x, y, rotated.cols, rotated.rows)));
  return rotated.cols;
}

// The 256 colours of the turbo map (blue, cyan, green, yellow, red), index 0 = zero error.
std::vector<cv::Vec3b> turbo_table() {
  cv::Mat ramp(1, 256, CV_8UC1);
  for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = static_cast<std::uint8_t>(i);
  cv::Mat colored;
  cv::applyColorMap(ramp, colored, cv::COLORMAP_TURBO);
  std::vector<cv::Vec3b> table(256);
  for (int i = 0; i < 256; ++i) table[static_cast<std::size_t>(i)] = colored.at<cv::Vec3b>(0, i);
  return table;
}

cv::Scalar color_of(const std::vector<cv::Vec3b>& table, double error, double color_max) {
  const double u = std::clamp(error / color_max, 0.0, 1.0);
  const cv::Vec3b c = table[static_cast<std::size_t>(std::lround(u * 255.0))];
  return {static_cast<double>(c[0]), static_cast<double>(c[1]), static_cast<double>(c[2])};
}

}  // namespace

cv::Mat render_error_heat_map(const std::vector<Eigen::Vector3d>& ground_truth,
                              const std::vector<Eigen::Vector3d>& estimate, const std::vector<double>& errors_m,
                              const ErrorPlotOptions& options) {
  if (estimate.empty()) throw std::invalid_argument("render_error_heat_map: no estimated positions");
  if (estimate.size() != errors_m.size())
    throw std::invalid_argument("render_error_heat_map: " + std::to_string(estimate.size()) + " positions but " +
                                std::to_string(errors_m.size()) + " errors");
  if (options.width < 320 || options.height < 240)
    throw std::invalid_argument("render_error_heat_map: the image must be at least 320 x 240 pixels");

  const int W = options.width, H = options.height;
  Fonts f{};
  f.scale = std::clamp(std::min(W / 1200.0, H / 900.0), 0.45, 2.5);
  f.tick = 0.5 * std::max(f.scale, 0.7);
  f.label = 0.6 * std::max(f.scale, 0.7);
  f.title = 0.7 * std::max(f.scale, 0.65);
  f.thickness = f.scale > 1.6 ? 2 : 1;
  const auto px = [&](double v) { return static_cast<int>(std::lround(v * f.scale)); };

  cv::Mat canvas(H, W, CV_8UC3, kWhite);

  // --- View plane: the two world axes along which the ground truth (or, without one, the
  // estimate) extends most, kept in x, y, z order (horizontal, vertical).
  const std::vector<Eigen::Vector3d>& reference = ground_truth.empty() ? estimate : ground_truth;
  Eigen::Vector3d low = reference.front(), high = reference.front();
  for (const auto& p : reference) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  const Eigen::Vector3d extent = high - low;
  std::array<int, 3> order{0, 1, 2};
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return extent(a) > extent(b); });
  const int axis_h = std::min(order[0], order[1]);
  const int axis_v = std::max(order[0], order[1]);
  const char* axis_names[] = {"x", "y", "z"};

  // --- Data bounds over both paths, padded, with equal aspect filling the plot area.
  double u_min = estimate.front()(axis_h), u_max = u_min, v_min = estimate.front()(axis_v), v_max = v_min;
  for (const auto* set : {&ground_truth, &estimate})
    for (const auto& p : *set) {
      u_min = std::min(u_min, p(axis_h));
      u_max = std::max(u_max, p(axis_h));
      v_min = std::min(v_min, p(axis_v));
      v_max = std::max(v_max, p(axis_v));
    }
  // Header: the title (row 1), the subtitle (row 2, left) and the legend (right-aligned on row 2,
  // or on a row of its own when the two do not fit side by side).
  const std::string gt_text = "ground truth", est_text = "estimate, coloured by ATE", start_text = "start";
  const int sample = px(34), gap = px(8), spacing = px(22);
  const int w_gt = text_size(gt_text, cv::FONT_HERSHEY_SIMPLEX, f.tick, f.thickness).width;
  const int w_est = text_size(est_text, cv::FONT_HERSHEY_SIMPLEX, f.tick, f.thickness).width;
  const int w_start = text_size(start_text, cv::FONT_HERSHEY_SIMPLEX, f.tick, f.thickness).width;
  const int legend_width = sample + gap + w_gt + spacing + sample + gap + w_est + spacing + px(16) + gap + w_start;
  const int subtitle_width =
      options.subtitle.empty() ? 0 : text_size(options.subtitle, cv::FONT_HERSHEY_SIMPLEX, f.tick, f.thickness).width;
  const int left = px(100), right = px(150), bottom = px(72);
  const int subtitle_row = px(60);
  const int legend_row = subtitle_width + px(30) + legend_width > W - left - right ? subtitle_row + px(26) : subtitle_row;
  const int top = legend_row + px(26);
  const cv::Rect plot(left, top, W - left - right, H - top - bottom);
  double span_u = u_max - u_min, span_v = v_max - v_min;
  const double span_floor = std::max({span_u, span_v, 1e-3}) * 0.05;  // a straight line still gets height
  span_u = std::max(span_u, span_floor) * 1.08;
  span_v = std::max(span_v, span_floor) * 1.08;
  const double pixels_per_m = std::min(plot.width / span_u, plot.height / span_v);
  const double view_u = plot.width / pixels_per_m, view_v = plot.height / pixels_per_m;
  const double u0 = 0.5 * (u_min + u_max) - 0.5 * view_u;
  const double v0 = 0.5 * (v_min + v_max) - 0.5 * view_v;
  // Plot-area pixel coordinates (the area is drawn as its own view, so anything outside clips).
  const auto to_pixel = [&](const Eigen::Vector3d& p) {
    return cv::Point2d((p(axis_h) - u0) * pixels_per_m, plot.height - (p(axis_v) - v0) * pixels_per_m);
  };
  constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 px
  const auto fixed = [](cv::Point2d p) {
    return cv::Point(static_cast<int>(std::lround(p.x * (1 << kShift))), static_cast<int>(std::lround(p.y * (1 << kShift))));
  };

  // --- Grid and ticks (same step on both axes: equal aspect).
  const double step = grid_step(std::max(view_u, view_v), 8.0);
  const int decimals = decimals_for(step);
  cv::Mat area = canvas(plot);
  for (double u = std::ceil(u0 / step) * step; u <= u0 + view_u; u += step) {
    const int x = static_cast<int>(std::lround((u - u0) * pixels_per_m));
    cv::line(area, {x, 0}, {x, plot.height - 1}, kGridColor, 1);
    cv::line(canvas, {plot.x + x, plot.y + plot.height}, {plot.x + x, plot.y + plot.height + px(6)}, kFrame, 1);
    const std::string label = fixed_decimals_label(u, decimals);
    const cv::Size size = text_size(label, cv::FONT_HERSHEY_SIMPLEX, f.tick, f.thickness);
    put(canvas, label, {plot.x + x - size.width / 2, plot.y + plot.height + px(10) + size.height}, f.tick, f.thickness);
  }
  int widest_v_label = 0;
  for (double v = std::ceil(v0 / step) * step; v <= v0 + view_v; v += step) {
    const int y = plot.height - static_cast<int>(std::lround((v - v0) * pixels_per_m));
    cv::line(area, {0, y}, {plot.width - 1, y}, kGridColor, 1);
    cv::line(canvas, {plot.x - px(6), plot.y + y}, {plot.x, plot.y + y}, kFrame, 1);
    const std::string label = fixed_decimals_label(v, decimals);
    const cv::Size size = text_size(label, cv::FONT_HERSHEY_SIMPLEX, f.tick, f.thickness);
    widest_v_label = std::max(widest_v_label, size.width);
    put(canvas, label, {plot.x - px(10) - size.width, plot.y + y + size.height / 2}, f.tick, f.thickness);
  }

  // --- Paths: ground truth underneath, estimate coloured by error on top.
  const std::vector<cv::Vec3b> table = turbo_table();
  double color_max = options.color_max_m.value_or(*std::max_element(errors_m.begin(), errors_m.end()));
  if (!(color_max > 0.0) || !std::isfinite(color_max)) color_max = 1e-3;
  const int gt_thickness = std::max(1, px(2));
  const int est_thickness = std::max(2, px(3));
  if (ground_truth.size() > 1) {
    std::vector<cv::Point> gt_points;
    gt_points.reserve(ground_truth.size());
    for (const auto& p : ground_truth) gt_points.push_back(fixed(to_pixel(p)));
    cv::polylines(area, gt_points, false, kGroundTruth, gt_thickness, cv::LINE_AA, kShift);
  }
  for (std::size_t i = 0; i + 1 < estimate.size(); ++i)
    cv::line(area, fixed(to_pixel(estimate[i])), fixed(to_pixel(estimate[i + 1])),
             color_of(table, 0.5 * (errors_m[i] + errors_m[i + 1]), color_max), est_thickness, cv::LINE_AA, kShift);
  // Dots at the poses when there are few enough to tell apart.
  if (estimate.size() <= 200)
    for (std::size_t i = 0; i < estimate.size(); ++i)
      cv::circle(area, fixed(to_pixel(estimate[i])), est_thickness * (1 << kShift), color_of(table, errors_m[i], color_max),
                 cv::FILLED, cv::LINE_AA, kShift);
  // Start of the ground truth (or of the estimate): a hollow black circle.
  const Eigen::Vector3d& start = ground_truth.empty() ? estimate.front() : ground_truth.front();
  cv::circle(area, fixed(to_pixel(start)), px(8) * (1 << kShift), kLabelColor, std::max(1, px(2)), cv::LINE_AA, kShift);
  cv::rectangle(canvas, plot, kFrame, 1);

  // --- Axis labels.
  const std::string x_label = std::string(axis_names[axis_h]) + " [m]";
  const std::string y_label = std::string(axis_names[axis_v]) + " [m]";
  {
    const cv::Size size = text_size(x_label, cv::FONT_HERSHEY_SIMPLEX, f.label, f.thickness);
    put(canvas, x_label, {plot.x + plot.width / 2 - size.width / 2, H - px(14)}, f.label, f.thickness);
  }
  {
    const cv::Size size = text_size(y_label, cv::FONT_HERSHEY_SIMPLEX, f.label, f.thickness);
    put_vertical(canvas, y_label, plot.x - px(16) - widest_v_label - size.height - px(8), plot.y + plot.height / 2,
                 f.label, f.thickness, px(3));
  }

  // --- Colour bar: 0 m at the bottom, color_max at the top, ticks in metres.
  const cv::Rect bar(W - right + px(30), plot.y, std::max(8, px(24)), plot.height);
  for (int row = 0; row < bar.height; ++row) {
    const double error = color_max * (1.0 - static_cast<double>(row) / std::max(1, bar.height - 1));
    cv::line(canvas, {bar.x, bar.y + row}, {bar.x + bar.width - 1, bar.y + row}, color_of(table, error, color_max), 1);
  }
  cv::rectangle(canvas, bar, kFrame, 1);
  const double bar_step = grid_step(color_max, 5.0);
  const int bar_decimals = decimals_for(bar_step);
  int widest_bar_label = 0;
  for (double e = 0.0; e <= color_max * (1.0 + 1e-9); e += bar_step) {
    const int y = bar.y + bar.height - 1 - static_cast<int>(std::lround(e / color_max * (bar.height - 1)));
    cv::line(canvas, {bar.x + bar.width, y}, {bar.x + bar.width + px(6), y}, kFrame, 1);
    const std::string label = fixed_decimals_label(e, bar_decimals);
    const cv::Size size = text_size(label, cv::FONT_HERSHEY_SIMPLEX, f.tick, f.thickness);
    widest_bar_label = std::max(widest_bar_label, size.width);
    put(canvas, label, {bar.x + bar.width + px(9), y + size.height / 2}, f.tick, f.thickness);
  }
  put_vertical(canvas, "ATE [m]", bar.x + bar.width + px(14) + widest_bar_label, bar.y + bar.height / 2, f.label,
               f.thickness, px(3));

  // --- Title, subtitle and legend.
  if (!options.title.empty()) {
    const cv::Size size = text_size(options.title, cv::FONT_HERSHEY_DUPLEX, f.title, f.thickness);
    put(canvas, options.title, {std::max(px(10), W / 2 - size.width / 2), px(12) + size.height}, f.title, f.thickness,
        cv::FONT_HERSHEY_DUPLEX);
  }
  if (!options.subtitle.empty()) put(canvas, options.subtitle, {plot.x, subtitle_row}, f.tick, f.thickness);
  {
    int x = plot.x + plot.width - legend_width;
    const int y = legend_row;
    const int mid = y - px(5);
    cv::line(canvas, {x, mid}, {x + sample, mid}, kGroundTruth, gt_thickness, cv::LINE_AA);
    put(canvas, gt_text, {x + sample + gap, y}, f.tick, f.thickness);
    x += sample + gap + w_gt + spacing;
    for (int k = 0; k < sample; ++k)
      cv::line(canvas, {x + k, mid - est_thickness / 2}, {x + k, mid + est_thickness / 2},
               color_of(table, color_max * k / (sample - 1.0), color_max), 1);
    put(canvas, est_text, {x + sample + gap, y}, f.tick, f.thickness);
    x += sample + gap + w_est + spacing;
    cv::circle(canvas, {x + px(8), mid}, px(7), kLabelColor, std::max(1, px(2)), cv::LINE_AA);
    put(canvas, start_text, {x + px(16) + gap, y}, f.tick, f.thickness);
  }
  return canvas;
}

cv::Mat render_evaluation_heat_map(const std::vector<Eigen::Vector3d>& ground_truth, const EvaluationResult& result,
                                   ErrorPlotOptions options) {
  if (options.title.empty()) options.title = evaluation_headline(result);
  if (options.subtitle.empty()) {
    std::array<char, 256> buffer{};
    std::snprintf(buffer.data(), buffer.size(), "ATE mean %.4g m, median %.4g m, max %.4g m | %zu of %zu poses matched",
                  result.ate_m.mean, result.ate_m.median, result.ate_m.max, result.association.pairs.size(),
                  result.association.estimate_count);
    options.subtitle = buffer.data();
  }
  return render_error_heat_map(ground_truth, result.estimate_positions_aligned, result.position_errors_m, options);
}

void write_png(const std::filesystem::path& file, const cv::Mat& image) {
  // Plots are flat colours on white: the slowest zlib level costs milliseconds and halves the file.
  write_image(file, image, ImageWriteOptions{.png = {.compression_level = 9}});
}

}  // namespace nirslam
