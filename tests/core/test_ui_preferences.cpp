// The operator's settings survive a restart, and a damaged settings file never stops the GUI: it
// falls back to defaults and says which file, line or field was wrong.

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/config/ui_preferences.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

class UiPreferencesTest : public ::testing::Test {
protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() /
              ("nirslam-prefs-" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }
  fs::path file() const { return folder_ / "nirslam" / "settings.json"; }
  fs::path folder_;
};

TEST_F(UiPreferencesTest, RoundTripKeepsEveryChoice) {
  UiPreferences p;
  remember_source(p, "sim:room@20W");
  remember_source(p, "/data/tunnel_run");
  p.sessions_folder = "/media/usb/sessions";
  p.strip_tab = "photometric";
  p.chosen_pipeline_mode = "odometry";
  p.recorded_speed = false;
  p.feed_corrected = true;
  p.view3d_follow = true;
  p.view3d_colour_by_error = false;
  p.window_width = 1920;
  p.window_height = 1080;
  p.window_x = 40;
  p.window_y = -10;
  save_preferences(file(), p);  // creates the folder
  const LoadedPreferences loaded = load_preferences(file());
  EXPECT_TRUE(loaded.warnings.empty());
  const UiPreferences& q = loaded.preferences;
  EXPECT_EQ(q.last_source, "/data/tunnel_run");
  ASSERT_EQ(q.recent_sources.size(), 2u);
  EXPECT_EQ(q.recent_sources[1], "sim:room@20W");
  EXPECT_EQ(q.sessions_folder, "/media/usb/sessions");
  EXPECT_EQ(q.strip_tab, "photometric");
  EXPECT_EQ(q.chosen_pipeline_mode, "odometry");
  EXPECT_FALSE(q.recorded_speed);
  EXPECT_TRUE(q.feed_corrected);
  EXPECT_TRUE(q.view3d_follow);
  EXPECT_FALSE(q.view3d_colour_by_error);
  EXPECT_EQ(q.window_width, 1920);
  EXPECT_EQ(q.window_x, 40);
  EXPECT_EQ(q.window_y, -10);
  EXPECT_FALSE(fs::exists(file().string() + ".tmp"));
}

TEST_F(UiPreferencesTest, MissingFileGivesDefaultsSilently) {
  const LoadedPreferences loaded = load_preferences(file());
  EXPECT_TRUE(loaded.warnings.empty());
  EXPECT_EQ(loaded.preferences.window_width, UiPreferences{}.window_width);
  EXPECT_TRUE(loaded.preferences.recent_sources.empty());
}

TEST_F(UiPreferencesTest, MalformedJsonNamesFileAndLine) {
  fs::create_directories(file().parent_path());
  std::ofstream(file()) << "{\n  \"last_source\": \"sim:room\",\n  \"strip_tab\": photometric\n}\n";
  const LoadedPreferences loaded = load_preferences(file());
  ASSERT_EQ(loaded.warnings.size(), 1u);
  EXPECT_NE(loaded.warnings[0].find(file().string() + ":3:"), std::string::npos) << loaded.warnings[0];
  EXPECT_EQ(loaded.preferences.strip_tab, "illumination");
}

TEST_F(UiPreferencesTest, WrongFieldTypeKeepsThatDefaultAndNamesTheField) {
  fs::create_directories(file().parent_path());
  std::ofstream(file()) << R"({"last_source": "sim:parking", "window_width": "wide", "recorded_speed": 3,
                               "window_x": 1.5})";
  const LoadedPreferences loaded = load_preferences(file());
  EXPECT_EQ(loaded.preferences.last_source, "sim:parking");
  EXPECT_EQ(loaded.preferences.window_width, 1440);
  EXPECT_TRUE(loaded.preferences.recorded_speed);
  EXPECT_FALSE(loaded.preferences.window_x);
  ASSERT_EQ(loaded.warnings.size(), 3u);
  std::string all;
  for (const std::string& warning : loaded.warnings) all += warning + "\n";
  for (const char* field : {"'window_width': expected number, found string", "'recorded_speed': expected boolean",
                            "'window_x': expected an integer"})
    EXPECT_NE(all.find(field), std::string::npos) << field << " in\n" << all;
}

TEST_F(UiPreferencesTest, AbsurdWindowSizeFallsBack) {
  fs::create_directories(file().parent_path());
  std::ofstream(file()) << R"({"window_width": 20, "window_height": 100000})";
  const LoadedPreferences loaded = load_preferences(file());
  EXPECT_EQ(loaded.preferences.window_width, 1440);
  EXPECT_EQ(loaded.preferences.window_height, 900);
  EXPECT_EQ(loaded.warnings.size(), 1u);
}

TEST_F(UiPreferencesTest, RecentSourcesAreUniqueAndBounded) {
  UiPreferences p;
  for (int i = 0; i < 12; ++i) remember_source(p, "source" + std::to_string(i));
  remember_source(p, "source9");
  ASSERT_EQ(p.recent_sources.size(), UiPreferences::kMaxRecentSources);
  EXPECT_EQ(p.recent_sources[0], "source9");
  EXPECT_EQ(p.recent_sources[1], "source11");
  EXPECT_EQ(std::count(p.recent_sources.begin(), p.recent_sources.end(), "source9"), 1);
  remember_source(p, "");
  EXPECT_EQ(p.last_source, "source9");
}

TEST_F(UiPreferencesTest, UnwritableFolderIsAnInputError) {
  fs::create_directories(folder_);
  std::ofstream(folder_ / "blocker") << "a file where a folder should be";
  EXPECT_THROW(save_preferences(folder_ / "blocker" / "settings.json", UiPreferences{}), InputError);
}

TEST(UiPreferencesPath, EnvironmentOverrides) {
  ::setenv("NIRSLAM_SETTINGS", "/tmp/x/settings.json", 1);
  EXPECT_EQ(default_preferences_path(), fs::path("/tmp/x/settings.json"));
  ::unsetenv("NIRSLAM_SETTINGS");
  ::setenv("XDG_CONFIG_HOME", "/tmp/cfg", 1);
  EXPECT_EQ(default_preferences_path(), fs::path("/tmp/cfg/nirslam/settings.json"));
  ::unsetenv("XDG_CONFIG_HOME");
}

}  // namespace
}  // namespace nirslam
