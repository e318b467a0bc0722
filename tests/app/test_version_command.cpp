// `nirslam --version`: the version and what the binary was built from, one "field: value" a line.

#include <cctype>
#include <filesystem>
#include <map>
#include <regex>
#include <sstream>
#include <string>

#include <Eigen/Core>
#include <gtest/gtest.h>
#include <opencv2/core/version.hpp>

#include "app/cli_runner.hpp"

namespace nirslam::testing {
namespace {

struct VersionOutput {
  std::string first_line;
  std::map<std::string, std::string> fields;
};

VersionOutput parse_version(const std::string& text) {
  VersionOutput parsed;
  std::istringstream in(text);
  std::getline(in, parsed.first_line);
  for (std::string line; std::getline(in, line);) {
    const auto colon = line.find(": ");
    if (colon != std::string::npos) parsed.fields[line.substr(0, colon)] = line.substr(colon + 2);
  }
  return parsed;
}

TEST(VersionCommand, FirstLineIsNameAndVersion) {
  const CommandResult r = run_command(nirslam("--version"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // help2man and scripts read the first line only.
  EXPECT_EQ(parse_version(r.output).first_line, std::string("nirslam ") + NIRSLAM_VERSION);
}

TEST(VersionCommand, PrintsEveryBuildField) {
  const CommandResult r = run_command(nirslam("--version"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const VersionOutput v = parse_version(r.output);
  for (const char* field : {"git", "commit", "build type", "compiler", "build date", "Dear ImGui", "OpenCV", "Eigen"})
    EXPECT_TRUE(v.fields.count(field)) << "no '" << field << ":' line in\n" << r.output;

  EXPECT_TRUE(std::regex_match(v.fields.at("build date"), std::regex(R"(\d{4}-\d{2}-\d{2})"))) << r.output;
  EXPECT_TRUE(std::regex_search(v.fields.at("compiler"), std::regex(R"(^\S+ \d+\.\d+)"))) << r.output;
  EXPECT_FALSE(v.fields.at("build type").empty());
  // Libraries: the versions the binary was compiled against, the same headers this test sees.
  EXPECT_EQ(v.fields.at("OpenCV"), CV_VERSION);
  EXPECT_EQ(v.fields.at("Eigen"), std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) +
                                      "." + std::to_string(EIGEN_MINOR_VERSION));
  EXPECT_TRUE(std::regex_match(v.fields.at("Dear ImGui"), std::regex(R"(\d+\.\d+.*)"))) << r.output;
}

TEST(VersionCommand, NamesACommitOfTheSourceRepository) {
  const std::filesystem::path source(NIRSLAM_SOURCE_DIR);
  if (!std::filesystem::exists(source / ".git")) GTEST_SKIP() << "sources are not a git checkout";
  const CommandResult r = run_command(nirslam("--version"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const VersionOutput v = parse_version(r.output);
  const std::string commit = v.fields.at("commit");
  ASSERT_TRUE(std::regex_match(commit, std::regex("[0-9a-f]{40}"))) << r.output;
  // Not compared with HEAD: a commit made since the last build is newer than the binary, rightly.
  EXPECT_EQ(run_command("git -C '" + source.string() + "' cat-file -e " + commit + "^{commit}").exit_code, 0)
      << commit << " is not a commit of " << source;
  // git describe names the same commit: "abc1234[-dirty]" untagged, "v1.0-3-gabc1234[-dirty]" after a tag.
  const std::string describe = v.fields.at("git"), abbreviated = commit.substr(0, 7);
  EXPECT_TRUE(describe.starts_with(abbreviated) || describe.find("-g" + abbreviated) != std::string::npos) << r.output;
}

TEST(VersionCommand, HelpEndsWithExamplesOfRealSubcommands) {
  const CommandResult r = run_command(nirslam("--help"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto examples = r.output.find("\nExamples:\n");
  ASSERT_NE(examples, std::string::npos) << r.output;
  // Every example's subcommand is listed above it ("  NAME   description" under Subcommands:).
  std::istringstream in(r.output.substr(examples));
  int checked = 0;
  const std::regex example(R"(^  nirslam ([a-z][a-z-]*)\b.*)");
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (!std::regex_match(line, m, example)) continue;
    EXPECT_NE(r.output.find("\n  " + m[1].str() + " "), std::string::npos) << "unknown subcommand in: " << line;
    ++checked;
  }
  EXPECT_GE(checked, 4);
}

}  // namespace
}  // namespace nirslam::testing
