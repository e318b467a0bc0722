#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "nirslam/common/error.hpp"
#include "nirslam/config/illumination_config.hpp"

namespace nirslam {
namespace {

namespace fs = std::filesystem;

fs::path write_illumination_yaml(const std::string& name, const std::string& text) {
  const fs::path file = fs::temp_directory_path() / ("nirslam_illumination_" + name + ".yaml");
  std::ofstream(file) << text;
  return file;
}

std::string illumination_config_error(const fs::path& file) {
  try {
    load_illumination_config(file);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(IlluminationConfig, ShippedFileLoads) {
  const IlluminationConfig config = load_illumination_config(fs::path(NIRSLAM_SOURCE_DIR) / "config/illumination.yaml");
  ASSERT_EQ(config.scenes.size(), 4u);
  EXPECT_EQ(config.scenes[0].name, "room");
  EXPECT_EQ(config.scenes[1].name, "outdoor");
  EXPECT_EQ(config.scenes[2].name, "parking");
  EXPECT_EQ(config.scenes[3].name, "tunnel");
  for (const SceneType& s : config.scenes) {
    ASSERT_TRUE(s.prior) << s.name;
    EXPECT_FALSE(s.prior->note.empty()) << s.name;
  }
  EXPECT_DOUBLE_EQ(config.advisor.plateau_share, 0.98);
  EXPECT_DOUBLE_EQ(config.advisor.max_saturated_fraction, 0.01);
  EXPECT_DOUBLE_EQ(config.exposure.max_saturated_fraction, 0.01);
  EXPECT_EQ(config.sweep.frames_per_power, 30);
  EXPECT_DOUBLE_EQ(config.illuminator.max_power_w, 150.0);
  EXPECT_NE(find_scene(config.scenes, "UNDERGROUND"), nullptr) << "aliases match in any case";
}

TEST(IlluminationConfig, EmptyFileKeepsDefaultsAndDefaultsHaveNoPriors) {
  const IlluminationConfig config = load_illumination_config(write_illumination_yaml("empty", ""));
  ASSERT_EQ(config.scenes.size(), 4u);
  for (const SceneType& s : config.scenes) EXPECT_FALSE(s.prior) << s.name;
  EXPECT_DOUBLE_EQ(config.advisor.plateau_share, AdvisorSettings{}.plateau_share);
}

TEST(IlluminationConfig, ErrorsNameFileLineAndField) {
  const fs::path typo = write_illumination_yaml("typo", "advisor:\n  plateau_share: 0.95\n  plateau_shar: 0.9\n");
  EXPECT_EQ(illumination_config_error(typo), typo.string() + ":3: field 'advisor.plateau_shar': unknown key");

  const fs::path range = write_illumination_yaml("range", "advisor:\n  plateau_share: 1.5\n");
  EXPECT_NE(illumination_config_error(range).find(":2: field 'advisor.plateau_share': value 1.5"), std::string::npos) << illumination_config_error(range);

  const fs::path power = write_illumination_yaml("power", "sweep:\n  powers_w: [0, 50, 400]\n");
  EXPECT_NE(illumination_config_error(power).find(":2: field 'sweep.powers_w[2]': value 400"), std::string::npos) << illumination_config_error(power);

  const fs::path list = write_illumination_yaml("list", "sweep:\n  powers_w: 50\n");
  EXPECT_NE(illumination_config_error(list).find(":2: field 'sweep.powers_w': expected a list"), std::string::npos) << illumination_config_error(list);

  const fs::path basis = write_illumination_yaml(
      "basis", "scenes:\n  - name: lab\n    prior: {low_w: 10, high_w: 20, basis: guess}\n");
  EXPECT_NE(illumination_config_error(basis).find(":3: field 'scenes[0].prior.basis': expected 'paper' or 'assumption', got 'guess'"),
            std::string::npos)
      << illumination_config_error(basis);

  const fs::path order = write_illumination_yaml(
      "order", "scenes:\n  - name: lab\n    prior: {low_w: 80, high_w: 20, basis: assumption}\n");
  EXPECT_NE(illumination_config_error(order).find("field 'scenes[0].prior.high_w': high_w is below low_w"), std::string::npos)
      << illumination_config_error(order);

  const fs::path duplicate =
      write_illumination_yaml("duplicate", "scenes:\n  - name: lab\n    aliases: [bench]\n  - name: bench\n");
  EXPECT_NE(illumination_config_error(duplicate).find(":4: field 'scenes[1]': the name 'bench' is used by an earlier scene"),
            std::string::npos)
      << illumination_config_error(duplicate);

  const fs::path nameless = write_illumination_yaml("nameless", "scenes:\n  - label: Lab\n");
  EXPECT_NE(illumination_config_error(nameless).find("field 'scenes[0].name': every scene needs a name"), std::string::npos)
      << illumination_config_error(nameless);

  const fs::path lamp = write_illumination_yaml("lamp", "illuminator:\n  min_power_w: 50\n  max_power_w: 20\n");
  EXPECT_NE(illumination_config_error(lamp).find(":3: field 'illuminator.max_power_w': max_power_w must exceed"), std::string::npos)
      << illumination_config_error(lamp);

  const fs::path syntax = write_illumination_yaml("syntax", "advisor: [\n");
  EXPECT_NE(illumination_config_error(syntax).find("not valid YAML"), std::string::npos) << illumination_config_error(syntax);
  EXPECT_NE(illumination_config_error(fs::temp_directory_path() / "nirslam_no_such_file.yaml").find("cannot open"), std::string::npos);
}

}  // namespace
}  // namespace nirslam
