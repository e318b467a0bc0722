#pragma once

#include <cstddef>
#include <optional>

#include "nirslam/worker/snapshot.hpp"
#include "ui/command_sink.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// The strip along the top: Start / Pause / Step / Stop, the worker state, the source, and the
// progress through a dataset. Buttons post commands and return at once. For a source that can
// jump (datasets, recorded sessions) the progress bar is a seek bar: a click or a drag posts
// command::Seek on release, and while dragging the readout shows the frame it will jump to.
class ControlBar {
public:
  void draw(const Snapshot& snapshot, const CommandSink& post);

  // Where the progress (seek) bar was drawn in the last frame; empty when it was not.
  const ScreenRect& progress_rect() const { return progress_rect_; }

private:
  std::optional<std::size_t> seek_target_;  // while the seek bar is dragged: the frame under the mouse
  ScreenRect progress_rect_;
};

// What the state badge shows: a label and its colour.
const char* state_label(WorkerState state);
unsigned state_colour(WorkerState state);

}  // namespace nirslam::ui
