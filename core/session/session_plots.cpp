#include "nirslam/session/session_plots.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace nirslam {
namespace {

const cv::Scalar kBackground(255, 255, 255);
const cv::Scalar kText(40, 40, 40);
const cv::Scalar kGrid(225, 225, 225);
const cv::Scalar kAxis(90, 90, 90);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

// Tick step of 1, 2 or 5 x 10^k giving about `count` ticks over `span`.
double nice_step(double span, int count) {
  if (span <= 0.0) return 1.0;
  const double raw = span / count;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (raw <= m * magnitude) return m * magnitude;
  return 10.0 * magnitude;
}

std::string tick_label(double value, double step) {
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  return fmt::format("{:.{}f}", std::abs(value) < step * 1e-6 ? 0.0 : value, decimals);
}

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool valid() const { return lo <= hi; }
  void pad() {
    if (hi - lo < 1e-9) {
      const double d = std::max(std::abs(lo) * 0.05, 0.5);
      lo -= d;
      hi += d;
    }
  }
};

void put_text(cv::Mat& image, const std::string& text, cv::Point origin, double scale = 0.5,
              const cv::Scalar& colour = kText, int thickness = 1) {
  cv::putText(image, text, origin, kFont, scale, colour, thickness, cv::LINE_AA);
}

int text_width(const std::string& text, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline).width;
}

// The plotting frame: data ranges mapped onto a pixel rectangle, with grid, ticks and labels.
struct Axes {
  cv::Rect area;
  Range x, y;
  cv::Point2d to_pixel(double vx, double vy) const {
    return {area.x + (vx - x.lo) / (x.hi - x.lo) * area.width, area.y + area.height - (vy - y.lo) / (y.hi - y.lo) * area.height};
  }
  void draw(cv::Mat& image, const std::string& x_label, const std::string& y_label) const {
    const double sx = nice_step(x.hi - x.lo, 8), sy = nice_step(y.hi - y.lo, 6);
    for (double v = std::ceil(x.lo / sx) * sx; v <= x.hi + sx * 1e-9; v += sx) {
      const int px = static_cast<int>(std::lround(to_pixel(v, y.lo).x));
      cv::line(image, {px, area.y}, {px, area.y + area.height}, kGrid, 1);
      const std::string label = tick_label(v, sx);
      put_text(image, label, {px - text_width(label, 0.45) / 2, area.y + area.height + 20}, 0.45);
    }
    for (double v = std::ceil(y.lo / sy) * sy; v <= y.hi + sy * 1e-9; v += sy) {
      const int py = static_cast<int>(std::lround(to_pixel(x.lo, v).y));
      cv::line(image, {area.x, py}, {area.x + area.width, py}, kGrid, 1);
      const std::string label = tick_label(v, sy);
      put_text(image, label, {area.x - 8 - text_width(label, 0.45), py + 5}, 0.45);
    }
    cv::rectangle(image, area, kAxis, 1);
    put_text(image, x_label, {area.x + area.width / 2 - text_width(x_label, 0.5) / 2, area.y + area.height + 44});
    if (!y_label.empty()) {
      // Vertical label: drawn horizontally, then rotated into the left margin.
      const int w = text_width(y_label, 0.5) + 4;
      cv::Mat label(24, w, CV_8UC3, kBackground);
      put_text(label, y_label, {2, 17});
      cv::Mat rotated;
      cv::rotate(label, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
      const int top = std::max(0, area.y + area.height / 2 - rotated.rows / 2);
      if (top + rotated.rows <= image.rows) rotated.copyTo(image(cv::Rect(4, top, rotated.cols, rotated.rows)));
    }
  }
};

void draw_title(cv::Mat& image, const std::string& title) {
  if (!title.empty()) put_text(image, title, {(image.cols - text_width(title, 0.65, 2)) / 2, 28}, 0.65, kText, 2);
}

void draw_legend(cv::Mat& image, const cv::Rect& area, const std::vector<std::pair<std::string, cv::Scalar>>& entries) {
  int y = area.y + 20;
  for (const auto& [label, colour] : entries) {
    if (label.empty()) continue;
    const int w = text_width(label, 0.45);
    const int x = area.x + area.width - w - 40;
    cv::rectangle(image, {x - 34, y - 13, w + 44, 20}, kBackground, cv::FILLED);
    cv::line(image, {x - 28, y - 4}, {x - 6, y - 4}, colour, 3, cv::LINE_AA);
    put_text(image, label, {x, y}, 0.45);
    y += 22;
  }
}

const cv::Scalar kSeriesColours[] = {{180, 110, 30}, {40, 120, 230}, {60, 160, 60}, {160, 60, 170}, {30, 30, 200}};

}  // namespace

cv::Mat render_line_plot(const std::vector<PlotSeries>& series, const LinePlotOptions& options) {
  if (options.width < 320 || options.height < 200) throw std::invalid_argument("render_line_plot: size under 320x200");
  Axes axes;
  for (const PlotSeries& s : series) {
    if (s.x.size() != s.y.size()) throw std::invalid_argument("render_line_plot: x and y differ in length in '" + s.label + "'");
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      axes.x.add(s.x[i]);
      axes.y.add(s.y[i]);
    }
  }
  if (!axes.x.valid()) throw std::invalid_argument("render_line_plot: no finite points to draw");
  axes.x.pad();
  axes.y.pad();
  const double margin = (axes.y.hi - axes.y.lo) * 0.05;
  axes.y.lo -= margin;
  axes.y.hi += margin;
  cv::Mat image(options.height, options.width, CV_8UC3, kBackground);
  axes.area = cv::Rect(80, 44, options.width - 110, options.height - 44 - 60);
  axes.draw(image, options.x_label, options.y_label);
  draw_title(image, options.title);
  std::vector<std::pair<std::string, cv::Scalar>> legend;
  for (const PlotSeries& s : series) {
    std::vector<cv::Point> points;
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      const cv::Point2d p = axes.to_pixel(s.x[i], s.y[i]);
      points.emplace_back(static_cast<int>(std::lround(p.x)), static_cast<int>(std::lround(p.y)));
    }
    if (points.size() == 1) cv::circle(image, points.front(), 3, s.colour, cv::FILLED, cv::LINE_AA);
    if (points.size() > 1) cv::polylines(image, points, false, s.colour, 2, cv::LINE_AA);
    legend.emplace_back(s.label, s.colour);
  }
  draw_legend(image, axes.area, legend);
  return image;
}

cv::Mat render_entropy_plot(const std::vector<JournalEntry>& journal) {
  PlotSeries entropy{{}, {}, kSeriesColours[0], "entropy"};
  for (const JournalEntry& e : journal) {
    if (!e.entropy_bits) continue;
    entropy.x.push_back(e.timestamp_s - journal.front().timestamp_s);
    entropy.y.push_back(*e.entropy_bits);
  }
  if (entropy.x.empty()) throw std::invalid_argument("render_entropy_plot: no frame has an entropy");
  return render_line_plot({entropy}, {1000, 420, "Image entropy over time", "time since the first frame (s)", "entropy (bit)"});
}

cv::Mat render_exposure_plot(const std::vector<JournalEntry>& journal, const std::vector<std::pair<double, double>>& estimated) {
  if (journal.empty()) throw std::invalid_argument("render_exposure_plot: empty journal");
  const double t0 = journal.front().timestamp_s;
  PlotSeries reported{{}, {}, kSeriesColours[1], "reported by the camera"};
  for (const JournalEntry& e : journal) {
    if (!e.exposure_ms) continue;
    reported.x.push_back(e.timestamp_s - t0);
    reported.y.push_back(*e.exposure_ms);
  }
  std::vector<PlotSeries> series;
  if (!reported.x.empty()) series.push_back(reported);
  if (!estimated.empty()) {
    // The estimate is relative (one scale is free): matched to the reported value at its first frame.
    double scale = 1.0;
    if (!reported.x.empty()) {
      for (const JournalEntry& e : journal) {
        if (e.exposure_ms && std::abs(e.timestamp_s - estimated.front().first) < 1e-6 && estimated.front().second > 0.0) {
          scale = *e.exposure_ms / estimated.front().second;
          break;
        }
      }
    }
    PlotSeries estimate{{}, {}, kSeriesColours[2], reported.x.empty() ? "estimated (relative)" : "estimated by the calibration"};
    for (const auto& [t, exposure] : estimated) {
      estimate.x.push_back(t - t0);
      estimate.y.push_back(exposure * scale);
    }
    series.push_back(estimate);
  }
  if (series.empty()) throw std::invalid_argument("render_exposure_plot: no exposures, reported nor estimated");
  return render_line_plot(series, {1000, 420, "Exposure over time", "time since the first frame (s)", "exposure (ms)"});
}

cv::Mat render_photometric_plot(const std::vector<double>& inverse_response, const cv::Mat& vignette) {
  if (inverse_response.size() < 2) throw std::invalid_argument("render_photometric_plot: no response values");
  PlotSeries response{{}, {}, kSeriesColours[0], "estimated G^-1"};
  PlotSeries linear{{}, {}, cv::Scalar(160, 160, 160), "linear"};
  const double n = static_cast<double>(inverse_response.size() - 1);
  for (std::size_t i = 0; i < inverse_response.size(); ++i) {
    response.x.push_back(static_cast<double>(i));
    response.y.push_back(inverse_response[i]);
    linear.x.push_back(static_cast<double>(i));
    linear.y.push_back(inverse_response.front() + (inverse_response.back() - inverse_response.front()) * static_cast<double>(i) / n);
  }
  const cv::Mat curve = render_line_plot({linear, response}, {620, 460, "Inverse response (pcalib.txt)", "grey level", "irradiance x exposure"});
  cv::Mat panel(460, 520, CV_8UC3, kBackground);
  draw_title(panel, "Vignette (vignette.png)");
  if (!vignette.empty()) {
    cv::Mat grey;
    vignette.convertTo(grey, CV_8UC1, 255.0);
    cv::Mat coloured;
    cv::applyColorMap(grey, coloured, cv::COLORMAP_TURBO);
    const double scale = std::min(440.0 / coloured.cols, 330.0 / coloured.rows);
    cv::Mat shown;
    cv::resize(coloured, shown, cv::Size(), scale, scale, cv::INTER_AREA);
    const int x = (panel.cols - shown.cols) / 2;
    shown.copyTo(panel(cv::Rect(x, 50, shown.cols, shown.rows)));
    // Colour bar 0..1 under the map.
    const int bar_y = 50 + shown.rows + 16;
    for (int i = 0; i < shown.cols; ++i) {
      cv::Mat value(1, 1, CV_8UC1, cv::Scalar(255.0 * i / std::max(1, shown.cols - 1)));
      cv::Mat colour;
      cv::applyColorMap(value, colour, cv::COLORMAP_TURBO);
      const cv::Vec3b c = colour.at<cv::Vec3b>(0, 0);
      cv::line(panel, {x + i, bar_y}, {x + i, bar_y + 14}, cv::Scalar(c[0], c[1], c[2]), 1);
    }
    put_text(panel, "0", {x - 4, bar_y + 34}, 0.45);
    put_text(panel, "1 (brightest)", {x + shown.cols - text_width("1 (brightest)", 0.45), bar_y + 34}, 0.45);
  } else {
    put_text(panel, "no vignette in this calibration", {40, 200});
  }
  cv::Mat both;
  cv::hconcat(curve, panel, both);
  return both;
}

cv::Mat render_trajectory_top_view(const std::vector<std::vector<Eigen::Vector3d>>& segments,
                                   const std::vector<Eigen::Vector3d>& ground_truth) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  std::size_t count = 0;
  const auto add = [&](const std::vector<Eigen::Vector3d>& path) {
    for (const Eigen::Vector3d& p : path) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      ++count;
    }
  };
  for (const auto& s : segments) add(s);
  add(ground_truth);
  if (count == 0) throw std::invalid_argument("render_trajectory_top_view: no positions");
  // The two axes with the largest extent span the view.
  const Eigen::Vector3d extent = hi - lo;
  int smallest = 0;
  for (int axis = 1; axis < 3; ++axis)
    if (extent[axis] < extent[smallest]) smallest = axis;
  const int a = smallest == 0 ? 1 : 0;
  const int b = smallest == 2 ? 1 : 2;
  const char* names = "xyz";
  Axes axes;
  axes.x.add(lo[a]);
  axes.x.add(hi[a]);
  axes.y.add(lo[b]);
  axes.y.add(hi[b]);
  axes.x.pad();
  axes.y.pad();
  const int width = 900, height = 760;
  axes.area = cv::Rect(80, 44, width - 110, height - 44 - 60);
  // Equal aspect: widen the narrower range around its centre.
  const double mpp = std::max((axes.x.hi - axes.x.lo) / axes.area.width, (axes.y.hi - axes.y.lo) / axes.area.height) * 1.08;
  const double cx = 0.5 * (axes.x.lo + axes.x.hi), cy = 0.5 * (axes.y.lo + axes.y.hi);
  axes.x = {cx - mpp * axes.area.width / 2, cx + mpp * axes.area.width / 2};
  axes.y = {cy - mpp * axes.area.height / 2, cy + mpp * axes.area.height / 2};
  cv::Mat image(height, width, CV_8UC3, kBackground);
  axes.draw(image, fmt::format("{} (m)", names[a]), fmt::format("{} (m)", names[b]));
  draw_title(image, "Trajectory, top view");
  const auto draw_path = [&](const std::vector<Eigen::Vector3d>& path, const cv::Scalar& colour, int thickness) {
    std::vector<cv::Point> points;
    for (const Eigen::Vector3d& p : path) {
      const cv::Point2d px = axes.to_pixel(p[a], p[b]);
      points.emplace_back(static_cast<int>(std::lround(px.x)), static_cast<int>(std::lround(px.y)));
    }
    if (points.size() > 1) cv::polylines(image, points, false, colour, thickness, cv::LINE_AA);
    if (!points.empty()) cv::circle(image, points.front(), 5, colour, cv::FILLED, cv::LINE_AA);
  };
  std::vector<std::pair<std::string, cv::Scalar>> legend;
  if (!ground_truth.empty()) {
    // Wide and light, so an estimate lying on it still lets it show at both sides.
    draw_path(ground_truth, cv::Scalar(150, 150, 150), 6);
    legend.emplace_back("ground truth", cv::Scalar(150, 150, 150));
  }
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const cv::Scalar& colour = kSeriesColours[i % std::size(kSeriesColours)];
    draw_path(segments[i], colour, 2);
    legend.emplace_back(segments.size() > 1 ? fmt::format("estimate, segment {}", i) : "estimate", colour);
  }
  draw_legend(image, axes.area, legend);
  return image;
}

}  // namespace nirslam
