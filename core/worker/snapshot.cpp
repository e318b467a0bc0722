#include "nirslam/worker/snapshot.hpp"

namespace nirslam {

const char* to_string(WorkerState state) {
  switch (state) {
    case WorkerState::Idle: return "idle";
    case WorkerState::Running: return "running";
    case WorkerState::Paused: return "paused";
    case WorkerState::Finished: return "finished";
    case WorkerState::Failed: return "failed";
  }
  return "unknown";
}

}  // namespace nirslam
