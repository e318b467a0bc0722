#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace nirslam {

// What the operator chose last time, restored when the GUI starts again: the source, the view
// options, the window. A plain value; the GUI copies it in at start and out at exit.
struct UiPreferences {
  std::string last_source;                  // as on the command line: "sim:tunnel@50W", a folder, ...
  std::vector<std::string> recent_sources;  // newest first, at most kMaxRecentSources
  std::string sessions_folder;              // where recordings go; empty: ~/nirslam-sessions
  std::string export_folder;                // where exports go; empty: next to the session
  std::string strip_tab = "illumination";   // "illumination", "photometric", "session", "record"
  // The mode the operator picked in the control bar (a PipelineMode name, or "auto"); empty: the
  // config's pipeline.mode. Saved as "chosen_pipeline_mode": before, "pipeline_mode" was written
  // with its default and never with a choice, so an old file's value says nothing.
  std::string chosen_pipeline_mode;
  bool recorded_speed = true;               // datasets at their own pace (false: as fast as possible)
  bool feed_corrected = false;              // the feed shows G(I)/V instead of the raw frame
  bool feed_clipping = true;
  bool feed_points = true;
  bool view3d_points = true;
  bool view3d_keyframes = true;
  bool view3d_ground_truth = true;
  bool view3d_follow = false;
  bool view3d_colour_by_error = true;   // by error when ground truth is known, else by time
  int window_width = 1440;
  int window_height = 900;
  std::optional<int> window_x;              // unset: the window system places the window
  std::optional<int> window_y;
  bool window_maximised = false;

  static constexpr std::size_t kMaxRecentSources = 8;
};

struct LoadedPreferences {
  UiPreferences preferences;
  // One line per field that could not be read (file, field, why): that field keeps its default.
  // A missing file is not a warning (first start).
  std::vector<std::string> warnings;
};

// $NIRSLAM_SETTINGS when set, else $XDG_CONFIG_HOME/nirslam/settings.json, else
// ~/.config/nirslam/settings.json.
std::filesystem::path default_preferences_path();

// Never throws: an unreadable or malformed file gives the defaults and says why in `warnings`.
LoadedPreferences load_preferences(const std::filesystem::path& file);

// Writes through a temporary file and a rename, so a crash never leaves half a settings file.
// Creates the folder. Throws InputError naming the file when it cannot be written.
void save_preferences(const std::filesystem::path& file, const UiPreferences& preferences);

// Puts `source` first in the recent list (no duplicates, bounded) and makes it the last source.
void remember_source(UiPreferences& preferences, const std::string& source);

}  // namespace nirslam
