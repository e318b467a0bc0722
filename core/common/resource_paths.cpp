#include "nirslam/common/resource_paths.hpp"

#include <cstdlib>
#include <system_error>

#include <spdlog/spdlog.h>

namespace nirslam {

std::filesystem::path executable_dir() {
  std::error_code error;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", error);
  return error ? std::filesystem::path{} : exe.parent_path();
}

std::vector<std::filesystem::path> resource_dir_candidates(const ResourceFolder& folder) {
  std::vector<std::filesystem::path> dirs;
  if (const char* env = std::getenv(folder.env_var.c_str()); env != nullptr && *env != '\0') dirs.emplace_back(env);
  if (const auto exe_dir = executable_dir(); !exe_dir.empty()) {
    dirs.push_back((exe_dir / ".." / NIRSLAM_INSTALLED_DATA_SUBDIR / folder.name).lexically_normal());
    dirs.push_back((exe_dir / NIRSLAM_INSTALLED_DATA_SUBDIR / folder.name).lexically_normal());
  }
  dirs.push_back(std::filesystem::path(NIRSLAM_SOURCE_DIR) / folder.name);
  return dirs;
}

std::filesystem::path find_resource_dir(const ResourceFolder& folder) {
  std::error_code error;
  if (const char* env = std::getenv(folder.env_var.c_str()); env != nullptr && *env != '\0') {
    if (!std::filesystem::is_directory(env, error))
      throw ResourceNotFound(folder.env_var + " is set to " + env + ", which is not a directory");
    spdlog::debug("{} folder: {} (from {})", folder.name, env, folder.env_var);
    return env;
  }
  std::string tried;
  for (const auto& dir : resource_dir_candidates(folder)) {
    if (std::filesystem::is_directory(dir, error)) {
      spdlog::debug("{} folder: {}", folder.name, dir.string());
      return dir;
    }
    tried += "\n  " + dir.string();
  }
  throw ResourceNotFound("cannot find the " + folder.name + " folder; looked in:" + tried + "\nset " +
                         folder.env_var + " to the folder that holds nirslam's " + folder.name);
}

}  // namespace nirslam
