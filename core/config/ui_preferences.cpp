#include "nirslam/config/ui_preferences.hpp"

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string environment(const char* name) {
  const char* value = std::getenv(name);
  return value == nullptr ? std::string() : std::string(value);
}

// Reads one field if present and of the right type; otherwise keeps the default and says why.
template <typename T>
void read_field(const json& document, const char* key, T& value, const fs::path& file,
                std::vector<std::string>& warnings) {
  const auto found = document.find(key);
  if (found == document.end() || found->is_null()) return;
  try {
    value = found->get<T>();
  } catch (const json::exception&) {
    warnings.push_back(fmt::format("{}: field '{}': expected {}, found {}; using the default", file.string(), key,
                                   json(value).type_name(), found->type_name()));
  }
}

void read_optional_int(const json& document, const char* key, std::optional<int>& value, const fs::path& file,
                       std::vector<std::string>& warnings) {
  const auto found = document.find(key);
  if (found == document.end() || found->is_null()) return;
  if (!found->is_number_integer()) {
    warnings.push_back(fmt::format("{}: field '{}': expected an integer, found {}; using the default", file.string(),
                                   key, found->type_name()));
    return;
  }
  value = found->get<int>();
}

}  // namespace

fs::path default_preferences_path() {
  if (const std::string file = environment("NIRSLAM_SETTINGS"); !file.empty()) return file;
  if (const std::string config = environment("XDG_CONFIG_HOME"); !config.empty())
    return fs::path(config) / "nirslam" / "settings.json";
  const std::string home = environment("HOME");
  return fs::path(home.empty() ? "." : home) / ".config" / "nirslam" / "settings.json";
}

LoadedPreferences load_preferences(const fs::path& file) {
  LoadedPreferences loaded;
  std::error_code error;
  if (!fs::exists(file, error)) return loaded;
  std::ifstream in(file);
  if (!in) {
    loaded.warnings.push_back(fmt::format("{}: cannot be read; using the default settings", file.string()));
    return loaded;
  }
  json document;
  try {
    document = json::parse(in);
  } catch (const json::parse_error& e) {
    // nlohmann reports a byte offset; the line is what an operator can find in an editor.
    std::ifstream again(file);
    std::string text((std::istreambuf_iterator<char>(again)), std::istreambuf_iterator<char>());
    const std::size_t upto = std::min<std::size_t>(e.byte, text.size());
    const long line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(upto), '\n');
    loaded.warnings.push_back(
        fmt::format("{}:{}: not valid JSON ({}); using the default settings", file.string(), line, e.what()));
    return loaded;
  }
  if (!document.is_object()) {
    loaded.warnings.push_back(fmt::format("{}: expected a JSON object; using the default settings", file.string()));
    return loaded;
  }
  UiPreferences& p = loaded.preferences;
  auto& w = loaded.warnings;
  read_field(document, "last_source", p.last_source, file, w);
  read_field(document, "recent_sources", p.recent_sources, file, w);
  if (p.recent_sources.size() > UiPreferences::kMaxRecentSources) p.recent_sources.resize(UiPreferences::kMaxRecentSources);
  read_field(document, "sessions_folder", p.sessions_folder, file, w);
  read_field(document, "export_folder", p.export_folder, file, w);
  read_field(document, "strip_tab", p.strip_tab, file, w);
  read_field(document, "chosen_pipeline_mode", p.chosen_pipeline_mode, file, w);
  read_field(document, "recorded_speed", p.recorded_speed, file, w);
  read_field(document, "feed_corrected", p.feed_corrected, file, w);
  read_field(document, "feed_clipping", p.feed_clipping, file, w);
  read_field(document, "feed_points", p.feed_points, file, w);
  read_field(document, "view3d_points", p.view3d_points, file, w);
  read_field(document, "view3d_keyframes", p.view3d_keyframes, file, w);
  read_field(document, "view3d_ground_truth", p.view3d_ground_truth, file, w);
  read_field(document, "view3d_follow", p.view3d_follow, file, w);
  read_field(document, "view3d_colour_by_error", p.view3d_colour_by_error, file, w);
  read_field(document, "window_width", p.window_width, file, w);
  read_field(document, "window_height", p.window_height, file, w);
  read_optional_int(document, "window_x", p.window_x, file, w);
  read_optional_int(document, "window_y", p.window_y, file, w);
  read_field(document, "window_maximised", p.window_maximised, file, w);
  // A window saved on a larger monitor than today's still opens; absurd sizes do not.
  const UiPreferences defaults;
  if (p.window_width < 800 || p.window_width > 8192 || p.window_height < 500 || p.window_height > 8192) {
    w.push_back(fmt::format("{}: window size {}x{} is outside 800x500..8192x8192; using {}x{}", file.string(),
                            p.window_width, p.window_height, defaults.window_width, defaults.window_height));
    p.window_width = defaults.window_width;
    p.window_height = defaults.window_height;
  }
  return loaded;
}

void save_preferences(const fs::path& file, const UiPreferences& p) {
  json document = {
      {"last_source", p.last_source},
      {"recent_sources", p.recent_sources},
      {"sessions_folder", p.sessions_folder},
      {"export_folder", p.export_folder},
      {"strip_tab", p.strip_tab},
      {"chosen_pipeline_mode", p.chosen_pipeline_mode},
      {"recorded_speed", p.recorded_speed},
      {"feed_corrected", p.feed_corrected},
      {"feed_clipping", p.feed_clipping},
      {"feed_points", p.feed_points},
      {"view3d_points", p.view3d_points},
      {"view3d_keyframes", p.view3d_keyframes},
      {"view3d_ground_truth", p.view3d_ground_truth},
      {"view3d_follow", p.view3d_follow},
      {"view3d_colour_by_error", p.view3d_colour_by_error},
      {"window_width", p.window_width},
      {"window_height", p.window_height},
      {"window_x", p.window_x ? json(*p.window_x) : json(nullptr)},
      {"window_y", p.window_y ? json(*p.window_y) : json(nullptr)},
      {"window_maximised", p.window_maximised},
  };
  std::error_code error;
  if (file.has_parent_path()) {
    fs::create_directories(file.parent_path(), error);
    if (error) throw InputError(file, "cannot create its folder: " + error.message());
  }
  fs::path temporary = file;
  temporary += ".tmp";
  {
    std::ofstream out(temporary, std::ios::trunc);
    if (!out) throw InputError(temporary, "cannot be written");
    out << document.dump(2) << '\n';
    out.flush();
    if (!out) throw InputError(temporary, "write failed (is the disk full?)");
  }
  fs::rename(temporary, file, error);
  if (error) {
    fs::remove(temporary, error);
    throw InputError(file, "cannot be replaced: " + error.message());
  }
}

void remember_source(UiPreferences& preferences, const std::string& source) {
  if (source.empty()) return;
  auto& recent = preferences.recent_sources;
  recent.erase(std::remove(recent.begin(), recent.end(), source), recent.end());
  recent.insert(recent.begin(), source);
  if (recent.size() > UiPreferences::kMaxRecentSources) recent.resize(UiPreferences::kMaxRecentSources);
  preferences.last_source = source;
}

}  // namespace nirslam
