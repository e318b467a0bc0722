#pragma once

// Whether a message or report mentions a part: what the tests of error texts and printed output check.

#include <string>

namespace nirslam {

inline bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace nirslam
