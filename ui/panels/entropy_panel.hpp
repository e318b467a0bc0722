#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "nirslam/quality/image_quality.hpp"
#include "nirslam/worker/snapshot.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// Image information entropy (the paper's Eq. 2-1, bits over 256 bins): the current value as a
// number and a 0..8 bit gauge, the saturated and black pixel fractions, the 256-bin histogram the
// entropy is computed from, and plots of entropy and clipping over the last frames.
class EntropyPanel {
public:
  // Draws into the current ImGui window, filling it.
  void draw(const Snapshot& snapshot);

  int history_frames = 300;  // frames shown in the plots (at most the snapshot's history)
  bool show_clipping_plot = true;
  bool auto_scale = false;   // entropy axis fitted to the values instead of 0..8 bits
  bool show_histogram = true;       // both optional sections give way in short windows

  static constexpr double kMaxBits = 8.0;
  static constexpr double kClippingBarRange = 0.10;  // the clipping bars span 0..10 % of the pixels

  // Geometry of the last draw(), in screen pixels, for the screenshot tests.
  const ScreenRect& gauge_rect() const { return gauge_; }       // the whole 0..8 bit track
  const ScreenRect& gauge_fill_rect() const { return fill_; }   // its filled part
  const ScreenRect& entropy_plot_rect() const { return entropy_plot_; }
  const ScreenRect& clipping_plot_rect() const { return clipping_plot_; }
  const ScreenRect& histogram_rect() const { return histogram_rect_; }

private:
  void draw_readout(const Snapshot& snapshot);
  void draw_gauge(double bits);
  void draw_clipping_bars(const ImageQuality& quality);
  void draw_histogram(const Snapshot& snapshot);
  void draw_history(const Snapshot& snapshot);

  ScreenRect gauge_;
  ScreenRect fill_;
  ScreenRect entropy_plot_;
  ScreenRect clipping_plot_;
  ScreenRect histogram_rect_;
  bool histogram_shown_ = false;  // this frame: the option, if the window is tall enough
  bool clipping_shown_ = false;
  // Reused between frames so the plots do not allocate every frame.
  std::vector<double> x_;
  std::vector<std::int64_t> index_;
  std::vector<double> entropy_;
  std::vector<double> saturated_;
  std::vector<double> black_;
};

}  // namespace nirslam::ui
