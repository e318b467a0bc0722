#pragma once

#include <filesystem>

#include <imgui.h>

#include "nirslam/worker/snapshot.hpp"
#include "ui/command_sink.hpp"
#include "ui/panels/control_bar.hpp"
#include "ui/panels/entropy_panel.hpp"
#include "ui/panels/feed_panel.hpp"
#include "ui/panels/illumination_panel.hpp"
#include "ui/panels/status_bar.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// Which parts of the layout are drawn. Tests render one panel alone.
struct PanelSet {
  bool controls = true;
  bool feed = true;
  bool entropy = true;
  bool illumination = true;
  bool status = true;
};

// The operator UI: owns the panels and their tiled layout and draws one UI frame from a
// snapshot. It reads snapshots and posts commands; it never waits on the worker.
//
// Dear ImGui 1.86 (Debian) has no docking branch, so the layout is a fixed tiling of windows
// that follows the display size: control strip on top, status line at the bottom, the feed on
// the left with the illumination strip under it, and the image-quality column on the right.
// Nothing overlaps.
class Application {
public:
  // Loads the panels' shaders from `shader_dir` (see gl::find_shader_dir()); throws
  // gl::ShaderError naming the file. Needs a current GL context and a UiContext.
  Application(const std::filesystem::path& shader_dir, CommandSink post);

  // Draws the whole layout, between UiContext::begin_frame() and end_frame(). Handles the
  // keyboard shortcuts: Space pauses or resumes, S steps one frame.
  void draw(const Snapshot& snapshot);

  struct Layout {
    ScreenRect controls;
    ScreenRect feed;
    ScreenRect entropy;
    ScreenRect illumination;
    ScreenRect status;
  };
  // The tiling for a display size with the current ImGui style and font (call inside a frame).
  Layout compute_layout(ImVec2 display) const;
  const Layout& layout() const { return layout_; }

  PanelSet panels;
  FeedPanel& feed() { return feed_; }
  EntropyPanel& entropy() { return entropy_; }
  IlluminationPanel& illumination() { return illumination_; }

private:
  void handle_shortcuts(const Snapshot& snapshot);

  CommandSink post_;
  ControlBar controls_;
  FeedPanel feed_;
  EntropyPanel entropy_;
  IlluminationPanel illumination_;
  StatusBar status_;
  Layout layout_;
};

}  // namespace nirslam::ui
