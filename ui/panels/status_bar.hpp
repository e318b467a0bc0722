#pragma once

#include "nirslam/worker/snapshot.hpp"

namespace nirslam::ui {

// The line along the bottom: the worker's last message, per-stage timings, UI frame rate and
// the keyboard shortcuts.
class StatusBar {
public:
  void draw(const Snapshot& snapshot);
};

}  // namespace nirslam::ui
