#pragma once

#include <string>
#include <string_view>

namespace nirslam {

// What a binary was built from and with, for `nirslam --version` and bug reports. The values are
// written into a header by the build (packaging/build_info.cmake): the git fields are refreshed on
// every build, so a binary never claims an older commit than the one it was built from.
struct BuildInfo {
  std::string_view version;         // project version, "0.1.0"
  std::string_view git_describe;    // `git describe --always --dirty --tags`; "" when not built from git
  std::string_view git_commit;      // full commit hash; "" when not built from git
  std::string_view build_type;      // CMAKE_BUILD_TYPE, plus the sanitizers when there are any
  std::string_view compiler;        // "GNU 12.2.0"
  std::string_view build_date;      // UTC, YYYY-MM-DD (SOURCE_DATE_EPOCH when set, for reproducible builds)
  std::string_view imgui_version;   // Dear ImGui linked in; "" in a build without the UI
  std::string_view opencv_version;  // OpenCV compiled against
  std::string_view eigen_version;   // Eigen compiled against
};

const BuildInfo& build_info();

// The `--version` text: "nirslam VERSION" on the first line (what help2man and scripts read), then
// one "field: value" line per BuildInfo field.
std::string version_text();

}  // namespace nirslam
