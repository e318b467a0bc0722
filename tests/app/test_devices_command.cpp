// `nirslam devices`: the emulated driver's cameras listed with their formats, sizes, rates and
// control ranges; a short capture from one with timestamps, exposures and the drops; and a node
// that does not exist named in the error.

#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "app/cli_runner.hpp"
#include "text_contains.hpp"

namespace nirslam::testing {
namespace {


TEST(DevicesCommand, ListsTheEmulatedCamerasWithFormatsRatesAndControls) {
  const CommandResult r = run_command(nirslam("devices --emulated"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "/dev/video0  Emulated NIR mono camera  (uvcvideo, usb-0000:00:14.0-1)")) << r.output;
  EXPECT_TRUE(contains(r.output, "/dev/video2  Emulated NIR stereo camera  (uvcvideo, usb-0000:00:14.0-2)")) << r.output;
  for (const char* format : {"GREY", "Y10", "Y12", "Y16", "YUYV", "MJPG"})
    EXPECT_TRUE(std::regex_search(r.output, std::regex(std::string("\\n    ") + format + " +"))) << format << "\n" << r.output;
  EXPECT_TRUE(contains(r.output, " 640x480 @ 60, 30, 15 fps")) << r.output;
  EXPECT_TRUE(contains(r.output, " 1280x480 @ 30, 15 fps")) << r.output;
  EXPECT_TRUE(contains(r.output, "(100 us units: 0.1..500 ms, now 10 ms)")) << r.output;
  EXPECT_TRUE(std::regex_search(r.output, std::regex("Gain +0..255 step 1, default 16"))) << r.output;
  EXPECT_TRUE(contains(r.output, "source: v4l2-emulated:/dev/video0")) << r.output;
}

TEST(DevicesCommand, CapturesFramesFromAnEmulatedCamera) {
  const CommandResult r = run_command(nirslam("devices --emulated --device /dev/video2 --capture 5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "side-by-side stereo (left view)")) << r.output;
  EXPECT_TRUE(contains(r.output, "640x480")) << r.output;  // the left half of 1280x480
  EXPECT_TRUE(contains(r.output, "5 frames,")) << r.output;
  EXPECT_TRUE(contains(r.output, "1000.000000")) << r.output;  // the emulated driver's first timestamp
}

TEST(DevicesCommand, UnknownNodeIsNamed) {
  const CommandResult r = run_command(nirslam("devices --emulated --device /dev/video9"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "error: /dev/video9: field 'open'")) << r.output;
}

TEST(DevicesCommand, WithoutCamerasItSaysSo) {
  // This machine has no /dev/video*; a machine with cameras lists them (either is a clean exit).
  const CommandResult r = run_command(nirslam("devices"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "No video capture devices") || contains(r.output, "/dev/video")) << r.output;
}

}  // namespace
}  // namespace nirslam::testing
