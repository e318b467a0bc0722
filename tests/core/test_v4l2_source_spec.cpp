// Source strings for V4L2 cameras: what each key sets, round trips, and malformed strings named
// by the string and the key.

#include <string>

#include <gtest/gtest.h>

#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

TEST(V4l2SourceSpec, ParsesEveryKey) {
  const V4l2SourceSpec s = parse_v4l2_source_spec(
      "v4l2:/dev/video4?format=Y16&size=640x480&fps=30&buffers=6&queue=3&stereo=sbs&exposure_ms=8.5&gain=24&lock=on"
      "&reconnect_s=1.5&stall_s=2&gain_unity=12");
  EXPECT_FALSE(s.emulated);
  EXPECT_EQ(s.device, "/dev/video4");
  EXPECT_EQ(s.format, PixelFormat::Y16);
  EXPECT_EQ(s.width, 640);
  EXPECT_EQ(s.height, 480);
  EXPECT_DOUBLE_EQ(s.fps, 30.0);
  EXPECT_EQ(s.buffer_count, 6);
  EXPECT_EQ(s.queue_capacity, 3);
  EXPECT_TRUE(s.stereo_side_by_side);
  EXPECT_DOUBLE_EQ(*s.exposure_ms, 8.5);
  EXPECT_DOUBLE_EQ(*s.gain, 24.0);
  EXPECT_TRUE(s.locked);
  EXPECT_DOUBLE_EQ(s.reconnect_wait_s, 1.5);
  EXPECT_DOUBLE_EQ(s.stall_timeout_s, 2.0);
  EXPECT_DOUBLE_EQ(s.gain_unity, 12.0);
  EXPECT_EQ(parse_v4l2_source_spec(s.to_string()).to_string(), s.to_string());
}

TEST(V4l2SourceSpec, EmulatedDefaultsAndStereoNode) {
  const V4l2SourceSpec mono = parse_v4l2_source_spec("v4l2-emulated:");
  EXPECT_TRUE(mono.emulated);
  EXPECT_EQ(mono.device, "/dev/video0");
  EXPECT_FALSE(mono.stereo_side_by_side);
  EXPECT_EQ(mono.to_string(), "v4l2-emulated:/dev/video0");
  const V4l2SourceSpec stereo = parse_v4l2_source_spec("v4l2-emulated:/dev/video2?frames=50&paced=off");
  EXPECT_TRUE(stereo.stereo_side_by_side);  // the emulated stereo camera
  EXPECT_EQ(stereo.emulated_frames, 50);
  EXPECT_FALSE(stereo.emulated_paced);
  EXPECT_FALSE(parse_v4l2_source_spec("v4l2-emulated:/dev/video2?stereo=none").stereo_side_by_side);
  EXPECT_TRUE(is_v4l2_source_string("v4l2:/dev/video0"));
  EXPECT_TRUE(is_v4l2_source_string("v4l2-emulated:"));
  EXPECT_FALSE(is_v4l2_source_string("sim:room"));
  EXPECT_FALSE(is_v4l2_source_string("/data/v4l2:x"));
}

void expect_error(const std::string& text, const std::string& field, const std::string& part) {
  try {
    parse_v4l2_source_spec(text);
    FAIL() << "expected an error for " << text;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), text);
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

TEST(V4l2SourceSpec, MalformedStringsNameTheKey) {
  expect_error("v4l2:/dev/video0?format=RGB3", "format", "not one of GREY, Y10, Y12, Y16, YUYV, MJPG");
  expect_error("v4l2:/dev/video0?size=640", "size", "not WIDTHxHEIGHT");
  expect_error("v4l2:/dev/video0?size=640xabc", "size", "not a number");
  expect_error("v4l2:/dev/video0?fps=0", "fps", "outside");
  expect_error("v4l2:/dev/video0?buffers=1", "buffers", "outside 2..32");
  expect_error("v4l2:/dev/video0?exposure=3", "exposure", "unknown key");
  expect_error("v4l2:/dev/video0?frames=3", "frames", "unknown key");  // emulator only
  expect_error("v4l2:/dev/video0?fps=30&fps=15", "fps", "given twice");
  expect_error("v4l2:/dev/video0?lock=maybe", "lock", "not on or off");
  expect_error("v4l2:video0", "device", "not a /dev/ node");
  expect_error("v4l2:/dev/video0?exposure_ms=5&auto_exposure=on", "exposure_ms", "auto_exposure=on");
  expect_error("v4l2:/dev/video0?stereo=tb", "stereo", "not sbs or none");
}

}  // namespace
}  // namespace nirslam
