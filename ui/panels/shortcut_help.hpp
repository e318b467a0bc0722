#pragma once

#include "ui/widgets.hpp"

namespace nirslam::ui {

// The keyboard shortcuts (ui/shortcuts.hpp) in a box centred over `area`, toggled with H.
class ShortcutHelp {
public:
  bool visible = false;
  void draw(const ScreenRect& area);
  const ScreenRect& drawn_rect() const { return drawn_; }

private:
  ScreenRect drawn_;
};

}  // namespace nirslam::ui
