// Camera files: every form of DSO's camera.txt, EuRoC's sensor.yaml (the real one), and errors
// that name the file and the line or field.

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "nirslam/camera/camera_io.hpp"
#include "nirslam/common/error.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

const fs::path kShared = NIRSLAM_SHARED_DATA_DIR;

DsoCameraCalibration parse(const std::string& text) {
  std::istringstream in(text);
  return parse_dso_camera(in, "camera.txt");
}

// The InputError message parsing `text` throws; fails the test if nothing is thrown.
std::string parse_error(const std::string& text) {
  try {
    parse(text);
  } catch (const InputError& error) {
    return error.what();
  }
  ADD_FAILURE() << "no InputError for:\n" << text;
  return {};
}

TEST(CameraIo, TumMonoVoRelativeFov) {
  // camera.txt of TUM monoVO sequence 01.
  const DsoCameraCalibration c = parse(
      "0.349153000000000 0.436593000000000 0.493140000000000 0.499021000000000 0.933271000000000\n"
      "1280 1024\ncrop\n640 480\n");
  ASSERT_EQ(c.input->type(), CameraModelType::Fov);
  EXPECT_EQ(c.input->width(), 1280);
  EXPECT_EQ(c.input->height(), 1024);
  // Relative to absolute with DSO's half-pixel shift.
  EXPECT_DOUBLE_EQ(c.input->fx(), 0.349153 * 1280);
  EXPECT_DOUBLE_EQ(c.input->fy(), 0.436593 * 1024);
  EXPECT_DOUBLE_EQ(c.input->cx(), 0.493140 * 1280 - 0.5);
  EXPECT_DOUBLE_EQ(c.input->cy(), 0.499021 * 1024 - 0.5);
  EXPECT_DOUBLE_EQ(dynamic_cast<const FovCamera&>(*c.input).omega(), 0.933271);
  EXPECT_EQ(c.output.mode, RectificationMode::Crop);
  EXPECT_EQ(c.output.width, 640);
  EXPECT_EQ(c.output.height, 480);
}

TEST(CameraIo, FiveNumbersWithZeroOmegaIsPinholeAndAbsoluteStaysAbsolute) {
  const DsoCameraCalibration c = parse("500 505 319.5 239.5 0\n640 480\nnone\n640 480\n");
  ASSERT_EQ(c.input->type(), CameraModelType::Pinhole);
  EXPECT_EQ(c.input->intrinsics(), Eigen::Vector4d(500, 505, 319.5, 239.5));
  EXPECT_EQ(c.output.mode, RectificationMode::SameK);
}

TEST(CameraIo, LegacyEightNumbersIsRadTanOnTheRealEurocEstimate) {
  // DSO-format calibration of the EuRoC cameras shipped with the photometric estimate.
  const DsoCameraCalibration c =
      read_dso_camera_file(kShared / "euroc_v1_01_micro/photometric_estimate/cameraLeft.txt");
  ASSERT_EQ(c.input->type(), CameraModelType::RadTan);
  EXPECT_EQ(c.input->intrinsics(), Eigen::Vector4d(458.654, 457.296, 367.215, 248.375));
  const Eigen::VectorXd d = c.input->distortion();
  ASSERT_EQ(d.size(), 4);
  EXPECT_DOUBLE_EQ(d[0], -0.28340811);
  EXPECT_DOUBLE_EQ(d[3], 1.76187114e-05);
  // "0.60991 0.95270 0.48832 0.51744 0.0" relative to 752x480.
  EXPECT_EQ(c.output.mode, RectificationMode::Explicit);
  EXPECT_DOUBLE_EQ(c.output.intrinsics[0], 0.60991 * 752);
  EXPECT_DOUBLE_EQ(c.output.intrinsics[1], 0.95270 * 480);
  EXPECT_DOUBLE_EQ(c.output.intrinsics[2], 0.48832 * 752 - 0.5);
  EXPECT_DOUBLE_EQ(c.output.intrinsics[3], 0.51744 * 480 - 0.5);
  EXPECT_EQ(c.output.width, 752);
  // The spec builds an undistorter.
  const Undistorter undistorter(*c.input, c.output);
  EXPECT_GT(undistorter.valid_fraction(), 0.9);
}

TEST(CameraIo, KeywordForms) {
  {
    const auto c = parse("RadTan 458.654 457.296 367.215 248.375 -0.28 0.07 0.0002 0.00002\n"
                         "752 480\nfull\n752 480\n");
    EXPECT_EQ(c.input->type(), CameraModelType::RadTan);
    EXPECT_EQ(c.output.mode, RectificationMode::Full);
  }
  {
    const auto c = parse("FOV 0.5 0.6 0.5 0.5 0.9\n640 480\ncrop\n320 240\n");
    EXPECT_EQ(c.input->type(), CameraModelType::Fov);
    EXPECT_DOUBLE_EQ(c.input->cx(), 319.5);
  }
  for (const char* keyword : {"EquiDistant", "KannalaBrandt", "kannalabrandt"}) {
    const auto c = parse(std::string(keyword) +
                         " 190.97 190.97 254.93 256.89 0.0034 0.0007 -0.0020 0.0002\n"
                         "512 512\n0.3 0.3 0.5 0.5 0\n512 512\n");
    EXPECT_EQ(c.input->type(), CameraModelType::Equidistant) << keyword;
    EXPECT_DOUBLE_EQ(c.input->distortion()[2], -0.0020);
    EXPECT_EQ(c.output.mode, RectificationMode::Explicit);
    EXPECT_DOUBLE_EQ(c.output.intrinsics[2], 255.5);
  }
  for (const char* line : {"Pinhole 500 500 320 240", "Pinhole 500 500 320 240 0"}) {
    const auto c = parse(std::string(line) + "\n640 480\nnone\n640 480\n");
    EXPECT_EQ(c.input->type(), CameraModelType::Pinhole) << line;
  }
  // Comments and Windows line ends are fine.
  const auto c = parse("# calibrated 2024-05-01\r\nPinhole 500 500 320 240\r\n640 480\r\ncrop\r\n"
                       "640 480\r\n");
  EXPECT_EQ(c.input->width(), 640);
}

TEST(CameraIo, MalformedCameraFilesNameTheLine) {
  // Missing lines (fields).
  {
    const std::string message = parse_error("500 505 319.5 239.5 0\n640 480\ncrop\n");
    EXPECT_NE(message.find("camera.txt:4"), std::string::npos) << message;
    EXPECT_NE(message.find("output size"), std::string::npos) << message;
  }
  EXPECT_NE(parse_error("").find("camera.txt:1"), std::string::npos);
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n").find("camera.txt:2"), std::string::npos);
  // Line 1: not a number, wrong count, unknown model, bad parameters.
  EXPECT_NE(parse_error("500 505 x 239.5 0\n640 480\ncrop\n640 480\n").find("camera.txt:1: 'x'"),
            std::string::npos);
  EXPECT_NE(parse_error("500 505 319.5 239.5 0 1\n640 480\ncrop\n640 480\n").find("camera.txt:1"),
            std::string::npos);
  EXPECT_NE(parse_error("Omni 1 2 3 4 5\n640 480\ncrop\n640 480\n").find("unknown camera model"),
            std::string::npos);
  EXPECT_NE(parse_error("RadTan 500 505 319.5 239.5 0.1\n640 480\ncrop\n640 480\n")
                .find("camera.txt:1: RadTan takes 8 numbers, got 5"),
            std::string::npos);
  EXPECT_NE(parse_error("FOV 500 505 319.5 239.5 4.0\n640 480\ncrop\n640 480\n")
                .find("camera.txt:1: FOV parameter omega"),
            std::string::npos);
  EXPECT_NE(parse_error("Pinhole 500 505 319.5 239.5 0.3\n640 480\ncrop\n640 480\n").find(":1:"),
            std::string::npos);
  EXPECT_NE(parse_error("-500 505 319.5 239.5 0\n640 480\ncrop\n640 480\n").find(":1:"),
            std::string::npos);
  // Line 2 and 4: sizes.
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n640\ncrop\n640 480\n").find("camera.txt:2"),
            std::string::npos);
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n640 -480\ncrop\n640 480\n").find("camera.txt:2"),
            std::string::npos);
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n640 480\ncrop\n640.5 480\n").find("camera.txt:4"),
            std::string::npos);
  // Line 3: rectification.
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n640 480\ncrap\n640 480\n").find("camera.txt:3"),
            std::string::npos);
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n640 480\n300 300 320 240 0\n640 480\n")
                .find("camera.txt:3: output intrinsics must be relative"),
            std::string::npos);
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n640 480\nnone\n320 240\n").find("camera.txt:4"),
            std::string::npos);
  // Trailing content.
  EXPECT_NE(parse_error("500 505 319.5 239.5 0\n640 480\ncrop\n640 480\n1 2\n").find("camera.txt:5"),
            std::string::npos);
  EXPECT_THROW(read_dso_camera_file("/nonexistent/camera.txt"), InputError);
}

TEST(CameraIo, RealEurocSensorYaml) {
  const EurocCameraSensor sensor =
      read_euroc_sensor_yaml(kShared / "euroc_v1_01_micro/mav0/cam0/sensor.yaml");
  ASSERT_NE(sensor.camera, nullptr);
  ASSERT_EQ(sensor.camera->type(), CameraModelType::RadTan);
  EXPECT_EQ(sensor.camera->width(), 752);
  EXPECT_EQ(sensor.camera->height(), 480);
  EXPECT_DOUBLE_EQ(sensor.camera->fx(), 458.654);
  EXPECT_DOUBLE_EQ(sensor.camera->fy(), 457.296);
  EXPECT_DOUBLE_EQ(sensor.camera->cx(), 367.215);
  EXPECT_DOUBLE_EQ(sensor.camera->cy(), 248.375);
  const auto& radtan = dynamic_cast<const RadTanCamera&>(*sensor.camera);
  EXPECT_DOUBLE_EQ(radtan.k1(), -0.28340811);
  EXPECT_DOUBLE_EQ(radtan.k2(), 0.07395907);
  EXPECT_DOUBLE_EQ(radtan.p1(), 0.00019359);
  EXPECT_DOUBLE_EQ(radtan.p2(), 1.76187114e-05);
  ASSERT_TRUE(sensor.rate_hz.has_value());
  EXPECT_DOUBLE_EQ(*sensor.rate_hz, 20.0);
  EXPECT_DOUBLE_EQ(sensor.T_body_sensor(0, 1), -0.999880929698);
  EXPECT_DOUBLE_EQ(sensor.T_body_sensor(2, 3), 0.00981073058949);
  // A rotation: orthonormal to the precision EuRoC printed.
  const Eigen::Matrix3d R = sensor.T_body_sensor.topLeftCorner<3, 3>();
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-9);
  EXPECT_NE(sensor.comment.find("MT9M034"), std::string::npos);
}

class SensorYamlErrors : public ::testing::Test {
protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    folder_ = fs::temp_directory_path() /
              ("nirslam_sensor_yaml_" + std::string(info->name()) + "_" +
               std::to_string(std::random_device{}()));
    fs::create_directories(folder_);
    std::ifstream real(kShared / "euroc_v1_01_micro/mav0/cam0/sensor.yaml");
    std::ostringstream content;
    content << real.rdbuf();
    real_ = content.str();
  }
  void TearDown() override { fs::remove_all(folder_); }

  // The error reading the real sensor.yaml with `from` replaced by `to`.
  std::string error_after_replacing(const std::string& from, const std::string& to) {
    std::string text = real_;
    const std::size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
    const fs::path file = folder_ / "sensor.yaml";
    std::ofstream(file) << text;
    try {
      read_euroc_sensor_yaml(file);
    } catch (const InputError& error) {
      EXPECT_EQ(error.file(), file);
      return error.what();
    }
    ADD_FAILURE() << "no InputError after replacing '" << from << "' by '" << to << "'";
    return {};
  }

  fs::path folder_;
  std::string real_;
};

TEST_F(SensorYamlErrors, NameTheFieldOrLine) {
  EXPECT_NE(error_after_replacing("intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv",
                                  "")
                .find("field 'intrinsics': missing"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("[458.654, 457.296, 367.215, 248.375]", "[458.654, 457.296]")
                .find("field 'intrinsics': expected a list of 4 numbers (line 19)"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("457.296", "fast").find("field 'intrinsics[1]'"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("radial-tangential", "omnidirectional")
                .find("field 'distortion_model': unsupported"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("camera_model: pinhole", "camera_model: omni")
                .find("field 'camera_model'"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("resolution: [752, 480]", "resolution: [752.5, 480]")
                .find("field 'resolution'"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("[-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]",
                                  "[-0.28340811, 0.07395907]")
                .find("field 'distortion_coefficients'"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("  cols: 4", "  cols: 3").find("field 'T_BS.cols'"),
            std::string::npos);
  EXPECT_NE(error_after_replacing("458.654, 457.296", "-458.654, 457.296")
                .find("field 'intrinsics': focal lengths"),
            std::string::npos);
  // A YAML syntax error names the line.
  EXPECT_NE(error_after_replacing("rate_hz: 20", "rate_hz: [20").find("sensor.yaml:"),
            std::string::npos);
}

TEST_F(SensorYamlErrors, EquidistantAndPinholeModels) {
  std::string text = real_;
  text.replace(text.find("radial-tangential"), 17, "equidistant");
  std::ofstream(folder_ / "equidistant.yaml") << text;
  EXPECT_EQ(read_euroc_sensor_yaml(folder_ / "equidistant.yaml").camera->type(),
            CameraModelType::Equidistant);
  text.replace(text.find("equidistant"), 11, "none");
  std::ofstream(folder_ / "none.yaml") << text;
  EXPECT_EQ(read_euroc_sensor_yaml(folder_ / "none.yaml").camera->type(), CameraModelType::Pinhole);
  // Without the OpenCV header it parses the same.
  std::ofstream(folder_ / "plain.yaml") << real_.substr(real_.find('\n') + 1);
  EXPECT_EQ(read_euroc_sensor_yaml(folder_ / "plain.yaml").camera->width(), 752);
}

}  // namespace
}  // namespace nirslam
