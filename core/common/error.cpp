#include "nirslam/common/error.hpp"

namespace nirslam {

InputError::InputError(const std::filesystem::path& file, const std::string& message)
    : std::runtime_error(file.string() + ": " + message), file_(file) {}

InputError::InputError(const std::filesystem::path& file, int line, const std::string& message)
    : std::runtime_error(file.string() + ":" + std::to_string(line) + ": " + message),
      file_(file),
      line_(line) {}

InputError::InputError(const std::filesystem::path& file, const std::string& field,
                       const std::string& message)
    : std::runtime_error(file.string() + ": field '" + field + "': " + message),
      file_(file),
      field_(field) {}

}  // namespace nirslam
