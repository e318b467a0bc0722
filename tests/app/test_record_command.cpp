#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "app/cli_runner.hpp"
#include "nirslam/session/session_source.hpp"

extern char** environ;

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

nlohmann::json session_json(const fs::path& session) {
  std::ifstream in(session / "session.json");
  return nlohmann::json::parse(in);
}

TEST(RecordCommand, RecordsTheDemoWithNotesAndReplaysItBitForBit) {
  const fs::path session = fresh_dir("record_demo") / "session";
  const CommandResult r = run_command(
      nirslam("record demo --frames 20 --mode quality --notes 'first pass, lamp 50 W' --out '" + session.string() + "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Recorded 20 frames"), std::string::npos) << r.output;
  const nlohmann::json json = session_json(session);
  EXPECT_EQ(json["state"], "complete");
  EXPECT_EQ(json["frames_written"], 20);
  EXPECT_EQ(json["notes"], "first pass, lamp 50 W");
  EXPECT_EQ(json["image"]["width"], 640);
  EXPECT_EQ(json["source"]["kind"], "demo");
  EXPECT_EQ(lines_of(session / "journal.csv").size(), 21u);
  EXPECT_EQ(lines_of(session / "metrics.csv").size(), 21u);
  SessionSource replay(session);
  EXPECT_EQ(replay.info().frame_count, 20u);
}

TEST(RecordCommand, RefusesAFolderThatIsNotEmpty) {
  const fs::path folder = fresh_dir("record_not_empty");
  std::ofstream(folder / "other.txt") << "x";
  const CommandResult r = run_command(nirslam("record demo --frames 5 --out '" + folder.string() + "'"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(folder.string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("not empty"), std::string::npos) << r.output;
}

// The acceptance test with the real binary: SIGKILL `nirslam record` mid-session, then
// `nirslam recover` keeps every frame the journal had, and the session exports.
TEST(RecordCommand, SigkilledRecordingIsRecoveredByTheRecoverCommand) {
  const fs::path dir = fresh_dir("record_kill");
  const fs::path session = dir / "session";
  const std::string executable = NIRSLAM_EXECUTABLE;
  const std::string out = session.string();
  std::vector<std::string> args = {executable, "record", "demo", "--mode", "quality", "--realtime", "--out", out};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t child = 0;
  ASSERT_EQ(posix_spawn(&child, executable.c_str(), &actions, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&actions);

  std::size_t journal_lines = 0;
  for (int i = 0; i < 600 && journal_lines < 16; ++i) {
    std::this_thread::sleep_for(50ms);
    journal_lines = lines_of(session / "journal.csv").size();
  }
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_GE(journal_lines, 16u) << "the recorder did not get going";
  EXPECT_EQ(session_json(session)["state"], "recording");

  const CommandResult recover = run_command(nirslam("recover '" + dir.string() + "'"));
  ASSERT_EQ(recover.exit_code, 0) << recover.output;
  EXPECT_NE(recover.output.find("1 unfinished session(s) recovered"), std::string::npos) << recover.output;
  const nlohmann::json json = session_json(session);
  EXPECT_EQ(json["state"], "recovered");
  EXPECT_GE(json["frames_written"].get<std::size_t>(), journal_lines - 1) << "every frame journaled before the kill";

  const CommandResult again = run_command(nirslam("recover '" + session.string() + "'"));
  EXPECT_NE(again.output.find("nothing to recover"), std::string::npos) << again.output;
  const CommandResult exported = run_command(nirslam("export '" + session.string() + "' --out '" + (dir / "export").string() + "'"));
  EXPECT_EQ(exported.exit_code, 0) << exported.output;
}

}  // namespace
}  // namespace nirslam::testing
