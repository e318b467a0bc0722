#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "app/cli_runner.hpp"
#include "nirslam/image/image_codec.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

double grey_stddev(const cv::Mat& image) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(image, mean, stddev);
  return stddev[0];
}

TEST(GuiCommand, HeadlessScreenshotShowsTheWholeWindow) {
  const fs::path shot = fresh_dir("gui_shot") / "gui.png";
  const CommandResult r =
      run_command(nirslam("gui --headless --frames 20 --size 960x600 --screenshot '" + shot.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Screenshot written to " + shot.string()), std::string::npos) << r.output;
  const cv::Mat image = nirslam::read_image(shot, nirslam::ImageReadMode::Grey);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 960);
  EXPECT_EQ(image.rows, 600);
  EXPECT_GT(grey_stddev(image), 10.0) << "not a blank image";
}

TEST(GuiCommand, HeadlessOnRealEurocData) {
  const fs::path shot = fresh_dir("gui_euroc") / "euroc.png";
  const fs::path dataset = fs::path(NIRSLAM_SHARED_DATA_DIR) / "euroc_v1_01_micro";
  const CommandResult r = run_command(nirslam("gui '" + dataset.string() +
                                              "' --headless --frames 10 --screenshot '" + shot.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(shot));
}

// --tab photometric brings the calibration's curves to the front: the estimate's orange lines fill
// the strip under the views, where the illumination tab has none.
TEST(GuiCommand, PhotometricTabShowsTheCalibrationCurves) {
  const auto orange_in_strip = [](const fs::path& shot) {
    cv::Mat image;
    try {
      image = nirslam::read_image(shot, nirslam::ImageReadMode::Bgr);
    } catch (const std::runtime_error&) {
      return -1;
    }
    int count = 0;
    for (int y = image.rows * 2 / 3; y < image.rows; ++y)
      for (int x = 0; x < image.cols * 6 / 10; ++x) {
        const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
        count += std::abs(p[2] - 245) < 30 && std::abs(p[1] - 158) < 30 && std::abs(p[0] - 50) < 30 ? 1 : 0;
      }
    return count;
  };
  const fs::path dir = fresh_dir("gui_tab");
  const CommandResult photometric = run_command(nirslam("gui sim:room --headless --frames 30 --size 960x600 --tab photometric "
                                                        "--screenshot '" + (dir / "photometric.png").string() + "'"));
  ASSERT_EQ(photometric.exit_code, 0) << photometric.output;
  const CommandResult illumination = run_command(nirslam("gui sim:room --headless --frames 30 --size 960x600 "
                                                         "--screenshot '" + (dir / "illumination.png").string() + "'"));
  ASSERT_EQ(illumination.exit_code, 0) << illumination.output;
  const int curves = orange_in_strip(dir / "photometric.png");
  EXPECT_GT(curves, 300);
  EXPECT_GT(curves, 3 * orange_in_strip(dir / "illumination.png"));

  const CommandResult bad = run_command(nirslam("gui --headless --tab odometry"));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("--tab"), std::string::npos) << bad.output;
}

TEST(GuiCommand, ErrorsNameWhatIsWrongBeforeAnyWork) {
  const CommandResult missing = run_command(nirslam("gui /nonexistent --headless"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find("/nonexistent"), std::string::npos) << missing.output;

  const CommandResult small = run_command(nirslam("gui --headless --size 100x20"));
  EXPECT_NE(small.exit_code, 0);
  EXPECT_NE(small.output.find("800x500"), std::string::npos) << small.output;

  const CommandResult folder = run_command(nirslam("gui --headless --screenshot /missing/x.png"));
  EXPECT_EQ(folder.exit_code, 1);
  EXPECT_NE(folder.output.find("/missing"), std::string::npos) << folder.output;

  const CommandResult shaders = run_command("NIRSLAM_SHADER_DIR=/nonexistent " + nirslam("gui --headless"));
  EXPECT_EQ(shaders.exit_code, 1);
  EXPECT_NE(shaders.output.find("NIRSLAM_SHADER_DIR"), std::string::npos) << shaders.output;
}

TEST(GuiCommand, NoEglIsAClearError) {
  const CommandResult r =
      run_command("__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json " + nirslam("gui --headless --frames 2"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("headless OpenGL (EGL) unavailable"), std::string::npos) << r.output;
}

// The README's main command on a machine without a display: renders headless and says where.
TEST(DefaultCommand, WithoutADisplayRendersHeadlessAndSaysWhere) {
  const fs::path dir = fresh_dir("gui_default");
  const CommandResult r =
      run_command("cd '" + dir.string() + "' && env -u DISPLAY -u WAYLAND_DISPLAY " + nirslam(""));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("No display"), std::string::npos) << r.output;
  const cv::Mat image = nirslam::read_image(dir / "nirslam-demo.png", nirslam::ImageReadMode::Grey);
  ASSERT_FALSE(image.empty()) << r.output;
  EXPECT_EQ(image.cols, 1280);
  EXPECT_EQ(image.rows, 800);
  EXPECT_GT(grey_stddev(image), 10.0);
}

}  // namespace
}  // namespace nirslam::testing

namespace nirslam::testing {
namespace {

// sim:SCENE@POWER sets the simulated lamp, /tripod stands the rig still and /exposure=MS locks the
// exposure (a power sweep for the response); a power that is not a number of watts, or an unknown
// option, is refused before any window opens, naming the argument.
TEST(GuiCommand, SimulatedLampPowerInTheSourceArgument) {
  const fs::path dir = fresh_dir("gui_power");
  const CommandResult ok = run_command(nirslam("gui sim:room@20W --headless --frames 3 --size 800x500 --screenshot '" +
                                               (dir / "room20.png").string() + "'"));
  ASSERT_EQ(ok.exit_code, 0) << ok.output;
  const CommandResult still = run_command(nirslam("gui sim:room@20W/tripod/exposure=4 --headless --frames 3 --size "
                                                  "800x500 --screenshot '" + (dir / "still.png").string() + "'"));
  ASSERT_EQ(still.exit_code, 0) << still.output;
  const std::pair<const char*, const char*> cases[] = {{"sim:room@", "'sim:room@'"},
                                                       {"sim:room@-5W", "must be a number of watts"},
                                                       {"sim:room@lots", "'sim:room@lots'"},
                                                       {"sim:cave@20W", "unknown simulated scene 'cave'"},
                                                       {"sim:room/wobbly", "unknown option 'wobbly'"},
                                                       {"sim:room/exposure=0", "exposure= must be milliseconds"}};
  for (const auto& [bad, says] : cases) {
    const CommandResult r = run_command(nirslam(std::string("gui ") + bad + " --headless --frames 3"));
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.output.find(says), std::string::npos) << r.output;
  }
}

// The UI benchmark prints frame-time statistics; the figures themselves are for the README.
TEST(GuiCommand, UiBenchmarkPrintsFrameTimes) {
  const fs::path dir = fresh_dir("gui_bench");
  const CommandResult r = run_command(nirslam("gui demo --headless --ui-benchmark --fast --frames 20 --size 800x500 "
                                              "--screenshot '" + (dir / "bench.png").string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("UI frame times, 800x500"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("median"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("frames/s while the worker processed"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nirslam::testing
