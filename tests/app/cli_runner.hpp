#pragma once

#include <array>
#include <cstdio>
#include <string>
#include <sys/wait.h>

namespace nirslam::testing {

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// Runs a shell command line and captures what it prints.
inline CommandResult run_command(const std::string& command_line) {
  CommandResult result;
  FILE* pipe = popen((command_line + " 2>&1").c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe)) result.output += buffer.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

inline std::string nirslam(const std::string& arguments) {
  return std::string("'") + NIRSLAM_EXECUTABLE + "' " + arguments;
}

}  // namespace nirslam::testing
