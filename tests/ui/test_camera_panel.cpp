// The camera controls panel and the device list rendered headless: the state banner's colour and
// text, the exposure slider drawn over the device's range (its grab where the value lies on the
// logarithmic scale, its label and value drawn), clicks that reach the controls, a refused change
// shown in red, a locked camera that ignores the sliders; the device list's rows and the source
// string its Open button gives. Ends with a real emulated camera driven through the panel.

#include <linux/videodev2.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/capture/device_info.hpp"
#include "nirslam/capture/emulated_uvc.hpp"
#include "nirslam/capture/v4l2_source.hpp"
#include "nirslam/common/error.hpp"
#include "ui/panels/camera_panel.hpp"
#include "ui/panels/device_list.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui {
namespace {

using testing::full_window;
using testing::near;
using testing::pixel;

// Records what the panel asked for; refuses a gain above 200 as a device would.
class RecordingControls final : public CameraControls {
public:
  CameraState state() const override { return {}; }
  void set_exposure_ms(double ms) override { exposure_ms.push_back(ms); }
  void set_gain(double g) override {
    if (g > 200.0) throw InputError("/dev/video0", "gain", "refused by the test device");
    gain.push_back(g);
  }
  void set_auto_exposure(bool on) override { auto_exposure.push_back(on); }
  void set_frame_rate(double fps) override { rates.push_back(fps); }
  void set_locked(bool locked) override { locks.push_back(locked); }

  std::vector<double> exposure_ms, gain, rates;
  std::vector<bool> auto_exposure, locks;
};

CameraState streaming_state(double exposure_ms) {
  CameraState s;
  s.device = "/dev/video0";
  s.card = "Test NIR camera";
  s.format = "Y12 640x480";
  s.width = 640;
  s.height = 480;
  s.bit_depth = 12;
  s.fps = 30.0;
  s.rates_fps = {60.0, 30.0, 15.0};
  s.buffer_count = 4;
  s.connection = CameraConnection::Streaming;
  s.exposure_ms = {true, 0.1, 500.0, 0.1, 10.0};
  s.gain = {true, 0.0, 255.0, 1.0, 16.0};
  s.fps_range = {true, 15.0, 60.0, 0.0, 30.0};
  s.auto_exposure_available = true;
  s.exposure_in_effect_ms = exposure_ms;
  s.gain_in_effect = 16.0;
  s.gain_unity = 16.0;
  s.frames_captured = 1234;
  s.frames_dropped_by_driver = 2;
  s.measured_fps = 29.9;
  return s;
}

class CameraPanelTest : public testing::HeadlessGlTest {
protected:
  void SetUp() override {
    HeadlessGlTest::SetUp();
    if (!IsSkipped() && !HasFatalFailure()) ui_ = std::make_unique<OffscreenUi>(460, 420);
  }
  void TearDown() override {
    ui_.reset();
    HeadlessGlTest::TearDown();
  }
  cv::Mat render(CameraPanel& panel, const CameraState& state, CameraControls* controls, int frames = 2, const char* name = nullptr) {
    for (int i = 0; i < frames; ++i) ui_->frame([&] { full_window([&] { panel.draw(state, controls); }); });
    cv::Mat shot = ui_->read_rgba();
    testing::save_if_requested(shot, name ? name : ::testing::UnitTest::GetInstance()->current_test_info()->name());
    return shot;
  }
  // Press and release the left button at `p`, one frame each, after a frame hovering there.
  void click(CameraPanel& panel, const CameraState& state, CameraControls* controls, ImVec2 p) {
    ImGuiIO& io = ImGui::GetIO();
    io.MousePos = p;
    render(panel, state, controls, 1);
    io.MouseDown[0] = true;
    render(panel, state, controls, 1);
    io.MouseDown[0] = false;
    render(panel, state, controls, 1);
    io.MousePos = ImVec2(-1.0f, -1.0f);
  }
  // Mean x of the slider grab's pixels in `rect`.
  static double grab_x(const cv::Mat& shot, const ScreenRect& rect) {
    const ImU32 grab = ImGui::GetColorU32(ImGuiCol_SliderGrab);
    double sum = 0.0;
    int n = 0;
    for (int y = static_cast<int>(rect.min.y); y < static_cast<int>(rect.max.y); ++y)
      for (int x = static_cast<int>(rect.min.x); x < static_cast<int>(rect.max.x); ++x)
        if (near(pixel(shot, x, y), grab, 6)) {
          sum += x;
          ++n;
        }
    return n > 0 ? sum / n : -1.0;
  }

  std::unique_ptr<OffscreenUi> ui_;
};

TEST_F(CameraPanelTest, StreamingShowsAGreenBannerAndTheExposureWhereItLies) {
  CameraPanel panel;
  RecordingControls controls;
  const cv::Mat short_shot = render(panel, streaming_state(1.0), &controls, 2, "CameraPanelShortExposure");
  const ScreenRect banner = panel.banner_rect();
  ASSERT_GT(banner.width(), 300.0f);
  EXPECT_TRUE(near(pixel(short_shot, ImVec2(banner.max.x - 4.0f, banner.centre().y)), colours::banner_ok, 3))
      << pixel(short_shot, ImVec2(banner.max.x - 4.0f, banner.centre().y));
  // The banner's text ("streaming /dev/video0") is drawn on it in the text colour.
  EXPECT_GT(testing::count_colour(short_shot, banner, colours::text, 40), 40);

  const ScreenRect slider = panel.exposure_slider_rect();
  ASSERT_GT(slider.width(), 150.0f);
  // The value is printed inside the slider: text-coloured pixels in its middle.
  EXPECT_GT(testing::count_colour(short_shot, slider, colours::text, 60), 20);
  const double x_short = grab_x(short_shot, slider);
  const cv::Mat long_shot = render(panel, streaming_state(100.0), &controls, 2, "CameraPanelLongExposure");
  const double x_long = grab_x(long_shot, panel.exposure_slider_rect());
  const cv::Mat max_shot = render(panel, streaming_state(500.0), &controls, 2, "CameraPanelMaxExposure");
  const double x_max = grab_x(max_shot, panel.exposure_slider_rect());
  ASSERT_GT(x_short, 0.0);
  // Logarithmic over the device's 0.1..500 ms: 1 ms left of the middle, 100 ms right of it, 500 ms at the end.
  const double centre = slider.centre().x;
  EXPECT_LT(x_short, centre);
  EXPECT_GT(x_long, centre + 0.15 * slider.width());
  EXPECT_GT(x_max, slider.max.x - 0.06 * slider.width());
  EXPECT_LT(x_long, x_max);
  // The label beside the slider ("Exposure") is drawn.
  const ScreenRect label{ImVec2(slider.max.x, slider.min.y), ImVec2(static_cast<float>(long_shot.cols), slider.max.y)};
  EXPECT_GT(testing::count_colour(long_shot, label, colours::text, 60), 20);
  EXPECT_TRUE(controls.exposure_ms.empty());  // drawing alone changes nothing
}

TEST_F(CameraPanelTest, UnpluggedIsAmberAndFailedIsRed) {
  CameraPanel panel;
  CameraState unplugged = streaming_state(10.0);
  unplugged.connection = CameraConnection::Unplugged;
  unplugged.message = "/dev/video0 was unplugged; 1234 frames captured before are kept; waiting for it to come back";
  cv::Mat shot = render(panel, unplugged, nullptr);
  ScreenRect banner = panel.banner_rect();
  EXPECT_GT(banner.height(), ImGui::GetTextLineHeight() * 1.9f);  // the long message wraps onto a second line
  EXPECT_TRUE(near(pixel(shot, ImVec2(banner.max.x - 4.0f, banner.centre().y)), colours::banner_dark, 3));

  CameraState failed = unplugged;
  failed.connection = CameraConnection::Failed;
  failed.error = "/dev/video0: field 'format': MJPG is not offered";
  shot = render(panel, failed, nullptr);
  banner = panel.banner_rect();
  EXPECT_TRUE(near(pixel(shot, ImVec2(banner.max.x - 4.0f, banner.centre().y)), colours::state_failed, 3));
}

TEST_F(CameraPanelTest, ClicksReachTheControls) {
  CameraPanel panel;
  RecordingControls controls;
  const CameraState state = streaming_state(10.0);
  render(panel, state, &controls);
  click(panel, state, &controls, panel.auto_exposure_rect().centre());
  ASSERT_EQ(controls.auto_exposure.size(), 1u);
  EXPECT_TRUE(controls.auto_exposure[0]);
  click(panel, state, &controls, panel.lock_rect().centre());
  ASSERT_EQ(controls.locks.size(), 1u);
  EXPECT_TRUE(controls.locks[0]);
  // A click near the right end of the exposure track: a long exposure, on the device's 0.1 ms step.
  const ScreenRect slider = panel.exposure_slider_rect();
  click(panel, state, &controls, ImVec2(slider.max.x - 6.0f, slider.centre().y));
  ASSERT_FALSE(controls.exposure_ms.empty());
  const double ms = controls.exposure_ms.back();
  EXPECT_GT(ms, 300.0);
  EXPECT_LE(ms, 500.0);
  EXPECT_NEAR(ms * 10.0, std::round(ms * 10.0), 1e-6);
}

TEST_F(CameraPanelTest, ARefusedChangeTurnsTheBannerRedWithTheReason) {
  CameraPanel panel;
  RecordingControls controls;
  const CameraState state = streaming_state(10.0);
  render(panel, state, &controls);
  const ScreenRect slider = panel.gain_slider_rect();
  ASSERT_GT(slider.width(), 100.0f);
  click(panel, state, &controls, ImVec2(slider.max.x - 4.0f, slider.centre().y));  // gain near 255: refused
  EXPECT_NE(panel.control_error().find("refused by the test device"), std::string::npos) << panel.control_error();
  const cv::Mat shot = render(panel, state, &controls);
  const ScreenRect banner = panel.banner_rect();
  EXPECT_TRUE(near(pixel(shot, ImVec2(banner.max.x - 4.0f, banner.centre().y)), colours::state_failed, 3));
}

TEST_F(CameraPanelTest, LockedCameraIgnoresTheSliders) {
  CameraPanel panel;
  RecordingControls controls;
  CameraState state = streaming_state(10.0);
  state.locked = true;
  render(panel, state, &controls);
  const ScreenRect slider = panel.exposure_slider_rect();
  click(panel, state, &controls, ImVec2(slider.max.x - 6.0f, slider.centre().y));
  const ScreenRect gain = panel.gain_slider_rect();
  click(panel, state, &controls, ImVec2(gain.min.x + 6.0f, gain.centre().y));
  EXPECT_TRUE(controls.exposure_ms.empty());
  EXPECT_TRUE(controls.gain.empty());
  click(panel, state, &controls, panel.lock_rect().centre());  // the lock itself still answers
  ASSERT_EQ(controls.locks.size(), 1u);
  EXPECT_FALSE(controls.locks[0]);
}

TEST_F(CameraPanelTest, DeviceListGivesTheSourceStringForTheChosenCamera) {
  EmulatedUvc emulator;
  emulator.add_camera(emulated_mono_nir_camera("/dev/video0"));
  emulator.add_camera(emulated_stereo_nir_camera("/dev/video2"));
  const std::vector<DeviceInfo> devices = enumerate_devices(emulator);
  DeviceList list;
  std::optional<std::string> opened;
  auto draw = [&](int frames) {
    for (int i = 0; i < frames; ++i)
      ui_->frame([&] {
        full_window([&] {
          if (auto s = list.draw(devices, true)) opened = s;
        });
      });
  };
  draw(2);
  ASSERT_EQ(list.device_rows().size(), 2u);
  EXPECT_EQ(list.selected_source(devices, true), "v4l2-emulated:/dev/video0?format=GREY&size=640x480&fps=60");
  const cv::Mat shot = ui_->read_rgba();
  testing::save_if_requested(shot, "DeviceList");
  EXPECT_GT(testing::count_colour(shot, list.device_rows()[1], colours::text, 60), 30);  // the second row's text

  ImGuiIO& io = ImGui::GetIO();
  for (const ImVec2 p : {list.device_rows()[1].centre(), ImVec2(-1.0f, -1.0f)}) {
    io.MousePos = p;
    draw(1);
    io.MouseDown[0] = p.x >= 0.0f;
    draw(1);
    io.MouseDown[0] = false;
    draw(1);
  }
  EXPECT_EQ(list.device, 1);
  EXPECT_TRUE(list.stereo_side_by_side);
  io.MousePos = list.open_button_rect().centre();
  draw(1);
  io.MouseDown[0] = true;
  draw(1);
  io.MouseDown[0] = false;
  draw(1);
  ASSERT_TRUE(opened.has_value());
  EXPECT_EQ(*opened, "v4l2-emulated:/dev/video2?format=GREY&size=1280x480&fps=30&stereo=sbs");
  // The string opens: the parser takes what the list gives.
  const V4l2SourceSpec spec = parse_v4l2_source_spec(*opened);
  EXPECT_TRUE(spec.stereo_side_by_side);
  EXPECT_EQ(spec.width, 1280);
}

TEST_F(CameraPanelTest, DrivesARealEmulatedCamera) {
  auto emulator = std::make_shared<EmulatedUvc>();
  EmulatedCameraSpec camera = emulated_mono_nir_camera("/dev/video0");
  camera.formats = {{PixelFormat::Grey, {{64, 48}}, {30.0, 15.0}}};
  camera.paced = false;
  emulator->add_camera(camera);
  V4l2SourceSpec spec;
  spec.queue_capacity = 2;
  const auto source = open_v4l2_source(spec, emulator);
  const auto controls = source->controls();
  CameraPanel panel;
  for (int i = 0; i < 3; ++i) source->next();
  render(panel, controls->state(), controls.get());
  click(panel, controls->state(), controls.get(), panel.auto_exposure_rect().centre());
  bool on = false;
  for (int i = 0; i < 100 && !on; ++i) {
    source->next();
    on = controls->state().auto_exposure;
  }
  EXPECT_TRUE(on);
  EXPECT_TRUE(panel.control_error().empty()) << panel.control_error();
}

}  // namespace
}  // namespace nirslam::ui
