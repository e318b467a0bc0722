#pragma once

#include <cstddef>
#include <optional>
#include <string>

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
  // Where the pipeline mode's combo was drawn in the last frame.
  const ScreenRect& mode_rect() const { return mode_rect_; }

  // The mode the operator picked in the mode combo ("auto" or a PipelineMode name), remembered
  // with the settings; empty until one is picked (the config's mode runs).
  std::string chosen_pipeline_mode;

private:
  std::optional<std::size_t> seek_target_;  // while the seek bar is dragged: the frame under the mouse
  ScreenRect progress_rect_;
  ScreenRect mode_rect_;
};

// What the state badge shows: a label and its colour.
const char* state_label(WorkerState state);
unsigned state_colour(WorkerState state);

}  // namespace nirslam::ui
