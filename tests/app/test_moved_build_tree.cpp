// A build tree carries its own shaders and config (<build>/share/nirslam, staged by the build), so the
// binary and that folder, copied anywhere, still run: the compiled-in source path is not needed.

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "app/cli_runner.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

// Copies the built binary and its staged share/ into a fresh folder, as a moved build tree.
fs::path moved_build_tree(const std::string& name) {
  const fs::path build = fs::path(NIRSLAM_EXECUTABLE).parent_path();
  const fs::path moved = fresh_dir(name);
  fs::copy_file(NIRSLAM_EXECUTABLE, moved / "nirslam");
  fs::copy(build / "share", moved / "share", fs::copy_options::recursive);
  return moved;
}

TEST(MovedBuildTree, RunReadsTheConfigNextToTheBinary) {
  const fs::path moved = moved_build_tree("moved_run");
  const CommandResult r = run_command("cd '" + moved.string() + "' && ./nirslam -v run demo --max-frames 2 -o out");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("config folder: " + (moved / "share/nirslam/config").string()), std::string::npos)
      << r.output;
  EXPECT_TRUE(fs::exists(moved / "out/summary.json"));
}

TEST(MovedBuildTree, HeadlessGuiReadsTheShadersNextToTheBinary) {
  const fs::path moved = moved_build_tree("moved_gui");
  const CommandResult r = run_command("cd '" + moved.string() +
                                      "' && ./nirslam -v gui demo --headless --frames 2 --size 800x500 --screenshot shot.png");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("shaders folder: " + (moved / "share/nirslam/shaders").string()), std::string::npos)
      << r.output;
  EXPECT_GT(fs::file_size(moved / "shot.png"), 10000u);
}

}  // namespace
}  // namespace nirslam::testing
