#pragma once

// Small pieces every line-oriented reader needs (times.txt, camera.txt, data.csv, trajectories):
// strict number parsing that rejects "1.5x", "nan" and "", and field splitting.

#include <charconv>
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace nirslam {

inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

inline std::string_view trim(std::string_view text) {
  while (!text.empty() && is_blank(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_blank(text.back())) text.remove_suffix(1);
  return text;
}

std::string lowercase(std::string_view text);

// Blank-separated fields; runs of blanks count as one separator.
std::vector<std::string_view> split_blanks(std::string_view line);

// Fields of a data line: comma-separated when it holds a comma (each field trimmed, empty ones
// kept so that they can be reported), else blank-separated.
std::vector<std::string_view> split_fields(std::string_view line);

// The whole token as a finite number, or nothing. A leading '+' is accepted.
inline std::optional<double> parse_double(std::string_view token) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  double value = 0.0;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (token.empty() || error != std::errc() || end != token.data() + token.size() || !std::isfinite(value))
    return std::nullopt;
  return value;
}

// The whole token as an integer of type T (no sign prefix '+', no fraction), or nothing.
template <typename T>
std::optional<T> parse_integer(std::string_view token) {
  T value{};
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (token.empty() || error != std::errc() || end != token.data() + token.size()) return std::nullopt;
  return value;
}

}  // namespace nirslam
