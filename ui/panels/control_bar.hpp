#pragma once

#include "nirslam/worker/snapshot.hpp"
#include "ui/command_sink.hpp"

namespace nirslam::ui {

// The strip along the top: Start / Pause / Step / Stop, the worker state, the source, and the
// progress through a dataset. Buttons post commands and return at once.
class ControlBar {
public:
  void draw(const Snapshot& snapshot, const CommandSink& post);
};

// What the state badge shows: a label and its colour.
const char* state_label(WorkerState state);
unsigned state_colour(WorkerState state);

}  // namespace nirslam::ui
