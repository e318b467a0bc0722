#pragma once

#include <span>

namespace nirslam::ui {

// Every keyboard shortcut of the window, in one table: the handler (Application) and the help
// overlay (H) both read it, so the help never lists a key that does nothing. Keys are typed
// characters (layout-aware, the same for the GLFW window and headless tests); they are ignored
// while a text field has the keyboard.
enum class ShortcutAction {
  StartPause,      // Space
  Step,            // S
  Stop,            // X
  ToggleCorrected, // C: the feed shows G(I)/V or the raw frame
  FitViews,        // F: fit the feed and the 3-D view
  FollowCamera,    // W: the 3-D view follows the current camera
  TopView,         // T
  SessionTab,      // O: open a source
  IlluminationTab, // I
  PhotometricTab,  // P
  ToggleRecording, // R: record / stop recording
  RecordTab,       // E: Record tab (sessions, export)
  CameraTab,       // K: Camera tab (exposure, gain, rate of a live camera)
  Help,            // H or ?: this list
};

struct Shortcut {
  char key;             // the typed character (lower case; upper case works too)
  const char* label;    // as the help shows it
  const char* action;   // what it does, for the operator
  ShortcutAction id;
};

std::span<const Shortcut> shortcuts();
// The action bound to a typed character, if any.
const Shortcut* shortcut_for(unsigned int character);

}  // namespace nirslam::ui
