// The lamp's keys in the pipeline configuration (odometry.light_offset, odometry.beam_exponent)
// and the illuminated modes by name.

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/config/pipeline_config.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

fs::path write_lamp_config_yaml(const std::string& name, const std::string& text) {
  const fs::path file = fs::temp_directory_path() / ("nirslam_lamp_config_" + name + ".yaml");
  std::ofstream(file) << text;
  return file;
}

TEST(IlluminatorConfig, LightOffsetBeamAndModeAreRead) {
  const PipelineConfig config = load_pipeline_config(write_lamp_config_yaml(
      "keys", "pipeline:\n  mode: illuminated\nodometry:\n  light_offset: [0.01, 0.025, -0.005]\n  beam_exponent: 4.8\n"
                "  surface_normals: false\n"));
  const OdometryOptions& o = config.worker.pipeline.odometry;
  EXPECT_EQ(config.worker.pipeline.mode, PipelineMode::Illuminated);
  EXPECT_DOUBLE_EQ(o.light_offset.x(), 0.01);
  EXPECT_DOUBLE_EQ(o.light_offset.y(), 0.025);
  EXPECT_DOUBLE_EQ(o.light_offset.z(), -0.005);
  EXPECT_DOUBLE_EQ(o.beam_exponent, 4.8);
  EXPECT_FALSE(o.lamp_surface_normals);
}

TEST(IlluminatorConfig, ShippedDefaultsPutTheLampAtTheCameraWithoutABeamTerm) {
  const PipelineConfig config = load_pipeline_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/pipeline.yaml");
  EXPECT_TRUE(config.worker.pipeline.odometry.light_offset.isZero());
  EXPECT_DOUBLE_EQ(config.worker.pipeline.odometry.beam_exponent, 0.0);
  EXPECT_TRUE(config.worker.pipeline.odometry.lamp_surface_normals);
}

TEST(IlluminatorConfig, BadValuesNameTheFieldAndLine) {
  auto error_of = [](const fs::path& file) -> std::string {
    try {
      load_pipeline_config(file);
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  const std::string short_offset = error_of(write_lamp_config_yaml("short", "odometry:\n  light_offset: [0.0, 0.05]\n"));
  EXPECT_NE(short_offset.find("odometry.light_offset"), std::string::npos) << short_offset;
  EXPECT_NE(short_offset.find("expected 3 numbers"), std::string::npos) << short_offset;
  EXPECT_NE(short_offset.find(":2"), std::string::npos) << short_offset;
  const std::string text = error_of(write_lamp_config_yaml("text", "odometry:\n  light_offset: [0.0, up, 0.0]\n"));
  EXPECT_NE(text.find("odometry.light_offset[1]"), std::string::npos) << text;
  const std::string beam = error_of(write_lamp_config_yaml("beam", "odometry:\n  beam_exponent: -1\n"));
  EXPECT_NE(beam.find("odometry.beam_exponent"), std::string::npos) << beam;
  const std::string mode = error_of(write_lamp_config_yaml("mode", "pipeline:\n  mode: lamp\n"));
  EXPECT_NE(mode.find("illuminated"), std::string::npos) << mode;
}

}  // namespace
}  // namespace nirslam
