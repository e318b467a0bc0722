// Enumeration and format negotiation through the seam, on the emulated UVC driver: what a camera
// offers, what is agreed, and the errors an operator sees for a busy device, a format or size the
// camera does not offer, and a control value out of range.

#include <linux/videodev2.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/capture/device_info.hpp"
#include "nirslam/capture/v4l2_camera.hpp"
#include "test_v4l2_fixtures.hpp"
#include "text_contains.hpp"

namespace nirslam {
namespace {

using testing::emulator_with;
using testing::small_camera;


TEST(V4l2Negotiation, EnumeratesDevicesFormatsSizesRatesAndControls) {
  auto emulator = std::make_shared<EmulatedUvc>();
  emulator->add_camera(emulated_mono_nir_camera("/dev/video0"));
  emulator->add_camera(emulated_stereo_nir_camera("/dev/video2"));
  const std::vector<DeviceInfo> devices = enumerate_devices(*emulator);
  ASSERT_EQ(devices.size(), 2u);
  const DeviceInfo& mono = devices[0];
  EXPECT_EQ(mono.node, "/dev/video0");
  EXPECT_EQ(mono.card, "Emulated NIR mono camera");
  EXPECT_EQ(mono.driver, "uvcvideo");
  EXPECT_EQ(mono.bus_info, "usb-0000:00:14.0-1");
  EXPECT_TRUE(mono.can_stream);
  ASSERT_EQ(mono.formats.size(), 6u);
  std::vector<std::string> names;
  for (const FormatInfo& f : mono.formats) {
    names.push_back(f.name);
    EXPECT_TRUE(f.supported) << f.name;
  }
  EXPECT_EQ(names, (std::vector<std::string>{"GREY", "Y10", "Y12", "Y16", "YUYV", "MJPG"}));
  ASSERT_EQ(mono.formats[3].sizes.size(), 2u);
  EXPECT_EQ(mono.formats[3].sizes[0].width, 640);
  EXPECT_EQ(mono.formats[3].sizes[0].height, 480);
  ASSERT_EQ(mono.formats[3].sizes[0].rates_fps.size(), 3u);
  EXPECT_EQ(mono.formats[3].sizes[0].rates_fps[0], 60.0);  // fastest first, from 100 ns intervals
  EXPECT_EQ(mono.formats[3].sizes[0].rates_fps[2], 15.0);

  const ControlInfo* exposure = find_control(mono.controls, V4L2_CID_EXPOSURE_ABSOLUTE);
  ASSERT_NE(exposure, nullptr);
  EXPECT_EQ(exposure->minimum, 1);
  EXPECT_EQ(exposure->maximum, 5000);
  EXPECT_EQ(exposure->value, 100);  // 10 ms in 100 us units
  const ControlInfo* autoexp = find_control(mono.controls, V4L2_CID_EXPOSURE_AUTO);
  ASSERT_NE(autoexp, nullptr);
  EXPECT_TRUE(autoexp->is_menu);
  ASSERT_NE(find_control(mono.controls, V4L2_CID_GAIN), nullptr);
  EXPECT_EQ(devices[1].bus_info, "usb-0000:00:14.0-2");
  EXPECT_EQ(devices[1].formats[0].sizes[0].width, 1280);

  emulator->unplug("/dev/video2");
  EXPECT_EQ(enumerate_devices(*emulator).size(), 1u);  // an unplugged node is gone from the listing
}

TEST(V4l2Negotiation, AgreesOnTheRequestedFormatSizeRateAndBuffers) {
  auto emulator = emulator_with(small_camera());
  V4l2Camera camera(emulator, "/dev/video0");
  const NegotiatedFormat f = camera.configure({PixelFormat::Y12, 32, 24, 15.0, 3});
  EXPECT_EQ(f.layout.format, PixelFormat::Y12);
  EXPECT_EQ(f.layout.width, 32);
  EXPECT_EQ(f.layout.height, 24);
  EXPECT_EQ(f.layout.bytes_per_line, 64);
  EXPECT_EQ(f.size_image, 64u * 24u);
  EXPECT_NEAR(f.fps, 15.0, 1e-6);
  EXPECT_EQ(f.buffer_count, 3);
  EXPECT_FALSE(f.uses_read);
  // A second descriptor cannot take the device while the first holds its buffers.
  V4l2Camera again(emulator, "/dev/video0");
  EXPECT_THROW(again.configure({}), InputError);
}

TEST(V4l2Negotiation, DefaultsAreTheFirstConvertibleFormatAndSize) {
  EmulatedCameraSpec spec = small_camera();
  // MJPG put first by copying into a vector of the final size: GCC 12 at -O3 reports a false null
  // dereference (-Wnull-dereference) inside vector::insert's reallocation when it inlines it here.
  std::vector<EmulatedFormat> formats(spec.formats.size() + 1);
  formats.front() = EmulatedFormat{PixelFormat::Mjpg, {{64, 48}}, {30.0}};
  std::copy(spec.formats.begin(), spec.formats.end(), formats.begin() + 1);
  spec.formats = std::move(formats);
  auto emulator = emulator_with(spec);
  V4l2Camera camera(emulator, "/dev/video0");
  const NegotiatedFormat f = camera.configure({});
  EXPECT_EQ(f.layout.format, PixelFormat::Mjpg);  // MJPG is convertible: first in the list wins
  EXPECT_EQ(f.layout.width, 64);
  EXPECT_NEAR(f.fps, 30.0, 1e-6);
  EXPECT_EQ(f.buffer_count, 4);
}

TEST(V4l2Negotiation, UnsupportedFormatAndSizeNameTheDeviceAndField) {
  auto emulator = emulator_with(small_camera());
  V4l2Camera camera(emulator, "/dev/video0");
  try {
    camera.configure({PixelFormat::Mjpg, 0, 0, 0.0, 4});
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/dev/video0");
    EXPECT_EQ(e.field(), "format");
    EXPECT_TRUE(contains(e.what(), "MJPG is not offered")) << e.what();
    EXPECT_TRUE(contains(e.what(), "GREY, Y10, Y12, Y16, YUYV")) << e.what();
  }
  try {
    camera.configure({PixelFormat::Grey, 640, 480, 0.0, 4});
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "size");
    EXPECT_TRUE(contains(e.what(), "640x480 is not offered in GREY; sizes: 64x48, 32x24")) << e.what();
  }
  EXPECT_THROW(camera.configure({PixelFormat::Grey, 64, 48, 0.0, 0}), InputError);  // no buffers
}

TEST(V4l2Negotiation, BusyDeviceIsAClearError) {
  auto emulator = emulator_with(small_camera());
  emulator->set_busy_elsewhere("/dev/video0", true);
  V4l2Camera camera(emulator, "/dev/video0");
  try {
    camera.configure({PixelFormat::Grey, 64, 48, 0.0, 4});
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/dev/video0");
    EXPECT_TRUE(contains(e.what(), "device is busy")) << e.what();
  }
  emulator->set_busy_elsewhere("/dev/video0", false);
  EXPECT_NO_THROW(camera.configure({PixelFormat::Grey, 64, 48, 0.0, 4}));
}

TEST(V4l2Negotiation, ControlsCheckTheirRangeAndFollowTheStep) {
  EmulatedCameraSpec spec = small_camera();
  spec.gain_min = 0, spec.gain_max = 100, spec.gain_step = 4;
  auto emulator = emulator_with(spec);
  V4l2Camera camera(emulator, "/dev/video0");
  try {
    camera.set_control(V4L2_CID_GAIN, 101);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/dev/video0");
    EXPECT_EQ(e.field(), "Gain");
    EXPECT_TRUE(contains(e.what(), "101 is outside the device's range 0..100")) << e.what();
  }
  EXPECT_EQ(camera.set_control(V4L2_CID_GAIN, 10), 12);  // the driver rounds to its step: read back
  EXPECT_THROW(camera.set_control(V4L2_CID_BRIGHTNESS, 1), InputError);  // no such control
  // Under auto exposure the driver refuses a manual exposure (EACCES), named.
  camera.set_control(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_APERTURE_PRIORITY);
  EXPECT_THROW(camera.set_control(V4L2_CID_EXPOSURE_ABSOLUTE, 50), InputError);
  camera.set_control(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(camera.set_control(V4L2_CID_EXPOSURE_ABSOLUTE, 50), 50);
}

TEST(V4l2Negotiation, MissingNodeAndReadOnlyDevice) {
  auto emulator = emulator_with(small_camera());
  try {
    V4l2Camera camera(emulator, "/dev/video7");
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/dev/video7");
    EXPECT_EQ(e.field(), "open");
  }
  // A driver without streaming I/O: frames come through read(), with the same conversion.
  EmulatedCameraSpec spec = small_camera("/dev/video1");
  spec.streaming_io = false;
  emulator->add_camera(spec);
  V4l2Camera camera(emulator, "/dev/video1");
  const NegotiatedFormat f = camera.configure({PixelFormat::Y10, 32, 24, 0.0, 4});
  EXPECT_TRUE(f.uses_read);
  camera.start();
  const auto image = camera.capture(100);
  ASSERT_TRUE(image.has_value());
  EXPECT_EQ(image->bit_depth, 10);
  EXPECT_EQ(image->image.at<std::uint16_t>(5, 7), 7);  // sequence 0: value = x
}

}  // namespace
}  // namespace nirslam
