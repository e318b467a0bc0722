#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "app/cli_runner.hpp"

namespace nirslam::testing {
namespace {

const std::filesystem::path kEurocFrames =
    std::filesystem::path(NIRSLAM_SHARED_DATA_DIR) / "euroc_v1_01_micro/mav0/cam0/data";

// Column 5 of the CSV row of `file`.
double entropy_from_csv(const std::string& output, const std::string& file) {
  std::istringstream lines(output);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind(file, 0) != 0) continue;
    std::istringstream fields(line);
    std::string field;
    for (int i = 0; i < 5; ++i) std::getline(fields, field, ',');
    return std::stod(field);
  }
  ADD_FAILURE() << "no row for " << file << " in:\n" << output;
  return -1.0;
}

// The brief's acceptance check: `nirslam entropy` on real images matches an independent computation
// (a standard-library-only Python PNG decoder, tests/tools/entropy_reference.py) to 1e-6 bits.
TEST(EntropyCommand, MatchesIndependentReferenceOnRealFrames) {
  const std::string frames[] = {(kEurocFrames / "1403715273262142976.png").string(),
                                (kEurocFrames / "1403715275262142976.png").string(),
                                (kEurocFrames / "1403715277062142976.png").string()};
  std::string files;
  for (const auto& f : frames) files += " '" + f + "'";
  const CommandResult ours = run_command(nirslam("entropy --csv" + files));
  ASSERT_EQ(ours.exit_code, 0) << ours.output;
  const CommandResult reference =
      run_command("python3 '" + std::string(NIRSLAM_SOURCE_DIR) + "/tests/tools/entropy_reference.py'" + files);
  ASSERT_EQ(reference.exit_code, 0) << reference.output;
  for (const auto& f : frames) {
    std::istringstream lines(reference.output);
    std::string path;
    double expected = -1;
    while (lines >> path) {
      double entropy, saturated, black;
      lines >> entropy >> saturated >> black;
      if (path == f) expected = entropy;
    }
    ASSERT_GT(expected, 0.0) << reference.output;
    EXPECT_NEAR(entropy_from_csv(ours.output, f), expected, 1e-6) << f;
  }
}

TEST(EntropyCommand, HumanReadableTableNamesColumnsAndUnits) {
  const CommandResult r = run_command(nirslam("entropy '" + (kEurocFrames / "1403715273262142976.png").string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("entropy[bit]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("752x480"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("6.973564"), std::string::npos) << r.output;
}

TEST(EntropyCommand, UnreadableImageIsNamedAndFailsTheCommand) {
  const auto bogus = std::filesystem::temp_directory_path() / "nirslam_not_an_image.png";
  { std::ofstream(bogus) << "this is not a PNG"; }
  const CommandResult r = run_command(nirslam("entropy '" + bogus.string() + "' '" +
                                              (kEurocFrames / "1403715273262142976.png").string() + "'"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(bogus.string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("cannot decode image"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("6.973564"), std::string::npos) << "the good image is still measured\n" << r.output;
  std::filesystem::remove(bogus);
}

TEST(EntropyCommand, MissingArgumentPrintsUsage) {
  const CommandResult r = run_command(nirslam("entropy"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("images"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nirslam::testing
