// Where shipped shaders/ and config/ are looked for: an explicit environment variable, the installed
// layout next to the executable, a build tree's staged copy, and only then the source tree.

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>

#include <gtest/gtest.h>

#include "nirslam/common/resource_paths.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

// Sets (or clears) an environment variable for one test and puts the old value back.
class ScopedEnv {
public:
  ScopedEnv(std::string name, const std::optional<std::string>& value) : name_(std::move(name)) {
    if (const char* old = std::getenv(name_.c_str())) old_ = old;
    if (value) ::setenv(name_.c_str(), value->c_str(), 1);
    else ::unsetenv(name_.c_str());
  }
  ~ScopedEnv() {
    if (old_) ::setenv(name_.c_str(), old_->c_str(), 1);
    else ::unsetenv(name_.c_str());
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

private:
  std::string name_;
  std::optional<std::string> old_;
};

const ResourceFolder kTestFolder{"shaders", "NIRSLAM_TEST_RESOURCE_DIR"};

TEST(ResourcePaths, InstalledLayoutThenBuildTreeThenSources) {
  const ScopedEnv no_override(kTestFolder.env_var, std::nullopt);
  const fs::path exe = executable_dir();
  ASSERT_FALSE(exe.empty());
  const auto dirs = resource_dir_candidates(kTestFolder);
  ASSERT_EQ(dirs.size(), 3u);
  // /usr/bin/nirslam -> /usr/share/nirslam/shaders; <build>/nirslam -> <build>/share/nirslam/shaders.
  EXPECT_EQ(dirs[0], (exe / "../share/nirslam/shaders").lexically_normal());
  EXPECT_EQ(dirs[1], (exe / "share/nirslam/shaders").lexically_normal());
  EXPECT_EQ(dirs[2], fs::path(NIRSLAM_SOURCE_DIR) / "shaders") << "the source tree is the last resort";
}

TEST(ResourcePaths, EnvironmentVariableComesFirstAndWins) {
  const fs::path dir = fs::temp_directory_path() / "nirslam_resource_paths_env";
  fs::create_directories(dir);
  const ScopedEnv override_dir(kTestFolder.env_var, dir.string());
  const auto dirs = resource_dir_candidates(kTestFolder);
  ASSERT_FALSE(dirs.empty());
  EXPECT_EQ(dirs.front(), dir);
  EXPECT_EQ(find_resource_dir(kTestFolder), dir);
}

TEST(ResourcePaths, MissingEnvironmentFolderIsAnErrorNotAFallThrough) {
  const std::string missing = (fs::temp_directory_path() / "nirslam_resource_paths_missing").string();
  fs::remove_all(missing);
  const ScopedEnv override_dir(kTestFolder.env_var, missing);
  try {
    find_resource_dir(kTestFolder);
    FAIL() << "expected ResourceNotFound";
  } catch (const ResourceNotFound& e) {
    EXPECT_NE(std::string(e.what()).find(kTestFolder.env_var), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
}

TEST(ResourcePaths, NotFoundListsEveryPlaceLooked) {
  const ScopedEnv no_override(kTestFolder.env_var, std::nullopt);
  const ResourceFolder absent{"no-such-folder-anywhere", kTestFolder.env_var};
  try {
    find_resource_dir(absent);
    FAIL() << "expected ResourceNotFound";
  } catch (const ResourceNotFound& e) {
    for (const fs::path& dir : resource_dir_candidates(absent))
      EXPECT_NE(std::string(e.what()).find(dir.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(absent.env_var), std::string::npos) << "says how to point at the folder";
  }
}

}  // namespace
}  // namespace nirslam
