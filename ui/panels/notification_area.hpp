#pragma once

#include <cstdint>
#include <deque>
#include <string>

#include "nirslam/worker/snapshot.hpp"
#include "ui/widgets.hpp"

namespace nirslam::ui {

// Messages the operator must see in the window, not only on a console: the worker failing (a
// source that cannot be read, a camera unplugged), a source refused, a settings file that could
// not be read, an export finished. Errors stay until dismissed; notices fade after a few seconds.
// Stacked in the top-right corner of `area` (the views), newest on top.
class NotificationArea {
public:
  enum class Severity { Notice, Warning, Error };

  void push(Severity severity, std::string text);
  // Watches the snapshots: a transition into Failed posts the worker's message as an error.
  void observe(const Snapshot& snapshot);
  void draw(const ScreenRect& area);

  std::size_t size() const { return items_.size(); }
  // Geometry of the last draw (the boxes' union), for the screenshot tests.
  const ScreenRect& drawn_rect() const { return drawn_; }

  static constexpr double kNoticeSeconds = 6.0;
  static constexpr std::size_t kMaxShown = 4;

private:
  struct Item {
    Severity severity;
    std::string text;
    double posted_at;  // ImGui time
    int repeats = 1;   // the same text posted again is counted, not stacked
  };
  std::deque<Item> items_;
  WorkerState last_state_ = WorkerState::Idle;
  std::uint64_t last_sequence_ = 0;
  ScreenRect drawn_;
};

}  // namespace nirslam::ui
