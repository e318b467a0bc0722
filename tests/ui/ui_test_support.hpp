#pragma once

// Shared pieces of the headless UI tests: an EGL context per test, a one-panel window, and pixel
// checks on read-back screenshots (CV_8UC4 RGBA, top row first).

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <ostream>
#include <string>

#include <gtest/gtest.h>
#include <imgui.h>
#include <opencv2/core.hpp>

#include "frontends/egl_context.hpp"
#include "nirslam/worker/snapshot.hpp"
#include "ui/theme.hpp"
#include "ui/ui_context.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui::testing {

// Every test gets its own surfaceless GL context. Without EGL the tests fail (they are the
// only check that the UI renders); NIRSLAM_SKIP_GL_TESTS=1 skips them on machines without Mesa.
class HeadlessGlTest : public ::testing::Test {
protected:
  void SetUp() override {
    if (const char* skip = std::getenv("NIRSLAM_SKIP_GL_TESTS"); skip != nullptr && std::string(skip) == "1")
      GTEST_SKIP() << "NIRSLAM_SKIP_GL_TESTS=1";
    try {
      egl_ = std::make_unique<app::EglContext>();
    } catch (const std::exception& e) {
      FAIL() << e.what();
    }
  }
  void TearDown() override { egl_.reset(); }

  std::unique_ptr<app::EglContext> egl_;
};

// Draws `body` in one undecorated window covering the whole display.
inline void full_window(const std::function<void()>& body) {
  ImGui::SetNextWindowPos(ImVec2(0.0f, 0.0f));
  ImGui::SetNextWindowSize(ImGui::GetIO().DisplaySize);
  ImGui::Begin("##test", nullptr, ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove |
                                     ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoScrollWithMouse);
  body();
  ImGui::End();
}

struct Rgb {
  int r = 0;
  int g = 0;
  int b = 0;
};

// A full left click at `at`: one UI frame (`draw`) each for the move, the press and the release,
// then the mouse leaves (one more frame), so hover effects do not linger into the next shot.
inline void click_at(ImVec2 at, const std::function<void()>& draw) {
  ImGuiIO& io = ImGui::GetIO();
  io.MousePos = at;
  draw();
  io.MouseDown[0] = true;
  draw();
  io.MouseDown[0] = false;
  draw();
  io.MousePos = ImVec2(-1.0f, -1.0f);
  draw();
}

inline std::ostream& operator<<(std::ostream& out, const Rgb& c) {
  return out << "rgb(" << c.r << ", " << c.g << ", " << c.b << ")";
}

inline Rgb pixel(const cv::Mat& rgba, int x, int y) {
  const cv::Vec4b p = rgba.at<cv::Vec4b>(y, x);
  return {p[0], p[1], p[2]};
}

inline Rgb pixel(const cv::Mat& rgba, ImVec2 p) {
  return pixel(rgba, static_cast<int>(std::floor(p.x)), static_cast<int>(std::floor(p.y)));
}

inline Rgb rgb_of(ImU32 colour) {
  return {static_cast<int>(colour & 0xFFu), static_cast<int>((colour >> 8) & 0xFFu),
          static_cast<int>((colour >> 16) & 0xFFu)};
}

inline bool near(const Rgb& a, const Rgb& b, int tolerance) {
  return std::abs(a.r - b.r) <= tolerance && std::abs(a.g - b.g) <= tolerance && std::abs(a.b - b.b) <= tolerance;
}

inline bool near(const Rgb& a, ImU32 colour, int tolerance) { return near(a, rgb_of(colour), tolerance); }

// The screen position of the centre of image pixel (x, y) in a drawn image rectangle.
inline ImVec2 image_to_screen(const ScreenRect& image, float scale, double x, double y) {
  return ImVec2(image.min.x + static_cast<float>((x + 0.5) * scale), image.min.y + static_cast<float>((y + 0.5) * scale));
}

// How many pixels of `region` are within `tolerance` of `colour`.
inline int count_colour(const cv::Mat& rgba, const ScreenRect& region, ImU32 colour, int tolerance) {
  int count = 0;
  const int x0 = std::max(0, static_cast<int>(region.min.x));
  const int y0 = std::max(0, static_cast<int>(region.min.y));
  const int x1 = std::min(rgba.cols, static_cast<int>(region.max.x));
  const int y1 = std::min(rgba.rows, static_cast<int>(region.max.y));
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) count += near(pixel(rgba, x, y), colour, tolerance) ? 1 : 0;
  return count;
}

// Standard deviation of the grey level inside a region: near 0 for a blank area.
inline double grey_stddev(const cv::Mat& rgba, const ScreenRect& region) {
  const cv::Rect rect(static_cast<int>(region.min.x), static_cast<int>(region.min.y), static_cast<int>(region.width()),
                      static_cast<int>(region.height()));
  cv::Mat grey;
  cv::extractChannel(rgba(rect & cv::Rect(0, 0, rgba.cols, rgba.rows)), grey, 1);
  cv::Scalar mean;
  cv::Scalar stddev;
  cv::meanStdDev(grey, mean, stddev);
  return stddev[0];
}

// With NIRSLAM_UI_TEST_SHOTS=<folder>, writes the screenshot there as <name>.png for a look.
void save_if_requested(const cv::Mat& rgba, const std::string& name);

// A snapshot with one frame and the measured quality, as the worker would publish it.
Snapshot snapshot_with_frame(Frame frame);

}  // namespace nirslam::ui::testing
