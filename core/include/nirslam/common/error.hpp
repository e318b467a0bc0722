#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

namespace nirslam {

// Every error that reaches an operator names where it came from: the file, and the line or field
// when there is one. Readers throw this instead of returning half-read data.
class InputError : public std::runtime_error {
public:
  InputError(const std::filesystem::path& file, const std::string& message);
  InputError(const std::filesystem::path& file, int line, const std::string& message);
  InputError(const std::filesystem::path& file, const std::string& field, const std::string& message);

  const std::filesystem::path& file() const { return file_; }
  int line() const { return line_; }          // 0 when the error is not tied to a line
  const std::string& field() const { return field_; }

private:
  std::filesystem::path file_;
  int line_ = 0;
  std::string field_;
};

}  // namespace nirslam
