#include "ui/shortcuts.hpp"

#include <array>

namespace nirslam::ui {
namespace {

constexpr std::array kShortcuts = {
    Shortcut{' ', "Space", "start or pause processing", ShortcutAction::StartPause},
    Shortcut{'s', "S", "step one frame (while paused)", ShortcutAction::Step},
    Shortcut{'x', "X", "stop and rewind the source", ShortcutAction::Stop},
    Shortcut{'c', "C", "feed: corrected G(I)/V or raw frame", ShortcutAction::ToggleCorrected},
    Shortcut{'f', "F", "fit the feed and the 3-D view", ShortcutAction::FitViews},
    Shortcut{'w', "W", "3-D view follows the camera (on/off)", ShortcutAction::FollowCamera},
    Shortcut{'t', "T", "3-D view from the top", ShortcutAction::TopView},
    Shortcut{'o', "O", "Session tab: open a source", ShortcutAction::SessionTab},
    Shortcut{'i', "I", "Illumination tab", ShortcutAction::IlluminationTab},
    Shortcut{'p', "P", "Photometric tab", ShortcutAction::PhotometricTab},
    Shortcut{'r', "R", "record / stop recording a session", ShortcutAction::ToggleRecording},
    Shortcut{'e', "E", "Record tab: sessions, replay, export", ShortcutAction::RecordTab},
    Shortcut{'k', "K", "Camera tab: exposure, gain, frame rate", ShortcutAction::CameraTab},
    Shortcut{'h', "H or ?", "show or hide this list", ShortcutAction::Help},
};

}  // namespace

std::span<const Shortcut> shortcuts() { return kShortcuts; }

const Shortcut* shortcut_for(unsigned int character) {
  if (character == '?') character = 'h';
  if (character >= 'A' && character <= 'Z') character = character - 'A' + 'a';
  for (const Shortcut& s : kShortcuts)
    if (static_cast<unsigned char>(s.key) == character) return &s;
  return nullptr;
}

}  // namespace nirslam::ui
