#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "commands/subcommand.hpp"
#include "nirslam/session/session_format.hpp"
#include "nirslam/session/session_recovery.hpp"

namespace nirslam::app {
namespace {

int recover_paths(const std::vector<std::filesystem::path>& paths) {
  int unfinished = 0;
  for (const std::filesystem::path& path : paths) {
    if (is_session_folder(path)) {
      const RecoveryReport report = recover_session(path);
      unfinished += report.was_unfinished ? 1 : 0;
      std::printf("%s\n", report.summary.c_str());
      continue;
    }
    if (!std::filesystem::is_directory(path)) {
      std::fprintf(stderr, "%s: not a session nor a folder of sessions\n", path.string().c_str());
      return 1;
    }
    const std::vector<RecoveryReport> reports = recover_unfinished_sessions(path);
    for (const RecoveryReport& report : reports) std::printf("%s\n", report.summary.c_str());
    unfinished += static_cast<int>(reports.size());
  }
  std::printf("%d unfinished session(s) recovered\n", unfinished);
  return 0;
}

}  // namespace

void add_recover_command(CLI::App& parent, CommandAction& action) {
  auto paths = std::make_shared<std::vector<std::filesystem::path>>();
  CLI::App* cmd = parent.add_subcommand(
      "recover", "Repair sessions a crash, power cut or full disk left unfinished (state 'recording'): drop partial "
                 "files, cut a torn journal line, keep every complete frame, mark them 'recovered'");
  cmd->add_option("paths", *paths, "Session folders, or folders holding sessions")->required();
  cmd->callback([paths, &action] { action = [paths] { return recover_paths(*paths); }; });
}

}  // namespace nirslam::app
