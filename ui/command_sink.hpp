#pragma once

#include <functional>

#include "nirslam/worker/worker.hpp"

namespace nirslam::ui {

// Where the UI sends what the operator asked for: normally Worker::post. Never blocks. An empty
// sink (tests rendering a hand-made snapshot) disables the controls.
using CommandSink = std::function<void(Command)>;

}  // namespace nirslam::ui
