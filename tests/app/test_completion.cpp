// Bash completion (packaging/completions/nirslam.bash) against the program's own --help: every
// subcommand and every option it lists must be offered, so the completion never goes stale; and
// the values it knows (choices, sources, files) come out as a shell user expects.

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "app/cli_runner.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

const fs::path kCompletionFile = fs::path(NIRSLAM_SOURCE_DIR) / "packaging/completions/nirslam.bash";

// What bash offers for the command line `line` (cursor at its end), as the function registered
// for `nirslam` computes it.
std::set<std::string> complete(const std::string& line, const fs::path& work_dir = fs::temp_directory_path()) {
  // One folder per test: ctest runs the tests of this file in parallel processes.
  const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
  const fs::path script = fresh_dir("completion_script_" + test) / "complete.sh";
  std::ofstream(script) << "source '" << kCompletionFile.string() << "' || exit 3\n"
                        << "cd '" << work_dir.string() << "' || exit 4\n"
                        << "COMP_LINE='" << line << "'; COMP_POINT=${#COMP_LINE}\n"
                        << "_nirslam\n"
                        << "printf '%s\\n' \"${COMPREPLY[@]}\"\n";
  const CommandResult r = run_command("bash '" + script.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  std::set<std::string> words;
  std::istringstream in(r.output);
  for (std::string word; std::getline(in, word);)
    if (!word.empty()) words.insert(word);
  return words;
}

std::string program() { return NIRSLAM_EXECUTABLE; }

// Entries of one section ("Subcommands:", "Options:") of a --help text, read independently of the
// completion's own parser: the first word of each line indented by exactly two spaces.
std::vector<std::string> section_entries(const std::string& help, const std::string& heading) {
  std::vector<std::string> entries;
  std::istringstream in(help);
  bool inside = false;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] != ' ') {
      inside = line == heading;
      continue;
    }
    if (inside && line.size() > 2 && line.compare(0, 2, "  ") == 0 && line[2] != ' ')
      entries.push_back(line.substr(2, line.find(' ', 2) - 2));
  }
  return entries;
}

std::vector<std::string> option_names(const std::string& help) {
  std::vector<std::string> names;
  for (const std::string& entry : section_entries(help, "Options:")) {
    std::istringstream parts(entry);
    for (std::string name; std::getline(parts, name, ',');) names.push_back(name);
  }
  return names;
}

std::string help_of(const std::string& subcommand) {
  const CommandResult r = run_command(nirslam(subcommand + " --help"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return r.output;
}

TEST(Completion, OffersExactlyTheSubcommandsOfHelp) {
  const std::vector<std::string> listed = section_entries(help_of(""), "Subcommands:");
  ASSERT_GE(listed.size(), 9u);
  EXPECT_EQ(complete(program() + " "), std::set<std::string>(listed.begin(), listed.end()));
  EXPECT_EQ(complete(program() + " cal"), (std::set<std::string>{"calibrate", "calibrate-sweep"}));
}

TEST(Completion, OffersEveryOptionOfEverySubcommand) {
  const std::string top_help = help_of("");
  for (const std::string& name : option_names(top_help))
    EXPECT_TRUE(complete(program() + " -").count(name)) << name;
  for (const std::string& subcommand : section_entries(top_help, "Subcommands:")) {
    const std::vector<std::string> options = option_names(help_of(subcommand));
    EXPECT_GE(options.size(), 2u) << subcommand;
    const std::set<std::string> offered = complete(program() + " " + subcommand + " -");
    for (const std::string& option : options)
      EXPECT_TRUE(offered.count(option)) << "nirslam " << subcommand << " " << option << " is not completed";
  }
}

TEST(Completion, OptionsAfterOtherArgumentsAndValues) {
  // The subcommand is found past global options, option values are not taken for positionals.
  const std::set<std::string> offered = complete(program() + " -v run demo -o out --max-frames 3 --m");
  EXPECT_EQ(offered, (std::set<std::string>{"--mode", "--max-frames"}));
}

TEST(Completion, ChoicesOfAnOption) {
  EXPECT_EQ(complete(program() + " run --mode "),
            (std::set<std::string>{"auto", "quality", "odometry", "calibrated", "illuminated", "odometry-illuminated"}));
  EXPECT_EQ(complete(program() + " run --mode=c"), (std::set<std::string>{"calibrated"}));
  EXPECT_EQ(complete(program() + " eval a b --align s"), (std::set<std::string>{"sim3", "se3"}));
  EXPECT_EQ(complete(program() + " simulate --scene p"), (std::set<std::string>{"parking"}));
  // A comma-separated list completes its last item.
  EXPECT_EQ(complete(program() + " bench --scenes room,t"), (std::set<std::string>{"room,tunnel"}));
}

TEST(Completion, SourcesAreSimulatedScenesDemoOrFolders) {
  const fs::path dir = fresh_dir("completion_sources");
  fs::create_directories(dir / "tunnel-run");
  std::ofstream(dir / "notes.txt") << "not a folder\n";
  const std::set<std::string> offered = complete(program() + " run ", dir);
  for (const char* source : {"sim:tunnel", "sim:room", "sim:parking", "sim:outdoor", "demo", "tunnel-run"})
    EXPECT_TRUE(offered.count(source)) << source;
  EXPECT_FALSE(offered.count("notes.txt")) << "a source is a folder, not a file";
  // bash splits words at ':', so after "sim:" only the scene is replaced.
  EXPECT_EQ(complete(program() + " gui sim:t", dir), (std::set<std::string>{"tunnel"}));
}

TEST(Completion, FileArguments) {
  const fs::path dir = fresh_dir("completion_files");
  std::ofstream(dir / "rig.yaml") << "pipeline: {}\n";
  EXPECT_EQ(complete(program() + " --config ri", dir), (std::set<std::string>{"rig.yaml"}));
  EXPECT_EQ(complete(program() + " eval r", dir), (std::set<std::string>{"rig.yaml"}));
  EXPECT_TRUE(complete(program() + " run --max-frames ", dir).empty()) << "a number has nothing to complete";
}

}  // namespace
}  // namespace nirslam::testing
