#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace nirslam {

// Shipped data folders (shaders/, config/) are found the same way from a build tree and from the
// installed package. For a folder NAME, in order:
//   1. the environment variable ENV (when set it must exist: an explicit choice never falls through),
//   2. <directory of the executable>/../share/nirslam/NAME (installed: /usr/bin -> /usr/share/nirslam;
//      also the test binaries in <build>/tests),
//   3. <directory of the executable>/share/nirslam/NAME (a build tree: the build copies the data there,
//      next to the binary, so a build tree moved away from its sources still runs),
//   4. the source tree's NAME/ (baked in at build time; the last resort, never the only way).
struct ResourceFolder {
  std::string name;     // "shaders", "config"
  std::string env_var;  // "NIRSLAM_SHADER_DIR", "NIRSLAM_CONFIG_DIR"
};

class ResourceNotFound : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

std::vector<std::filesystem::path> resource_dir_candidates(const ResourceFolder& folder);

// The first existing candidate (logged at debug level, `nirslam -v`). Throws ResourceNotFound listing
// every place it looked.
std::filesystem::path find_resource_dir(const ResourceFolder& folder);

// The folder of the running executable; empty when it cannot be told.
std::filesystem::path executable_dir();

inline const ResourceFolder kShaderFolder{"shaders", "NIRSLAM_SHADER_DIR"};
inline const ResourceFolder kConfigFolder{"config", "NIRSLAM_CONFIG_DIR"};

}  // namespace nirslam
