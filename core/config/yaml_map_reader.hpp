#pragma once

// Private to core/config: reads the keys of one YAML map into typed values, remembering which were
// used so that leftovers (typos) can be reported. Every error is an InputError naming the file, the
// line and the dotted field ("pipeline.yaml:3: field 'demo.hieght': unknown key").

#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "nirslam/common/error.hpp"

namespace nirslam::config_detail {

class YamlMapReader {
public:
  YamlMapReader(const YAML::Node& node, std::filesystem::path file, std::string prefix)
      : node_(node), file_(std::move(file)), prefix_(std::move(prefix)) {
    if (node_ && !node_.IsMap()) fail(node_, prefix_, "expected a map of keys");
  }

  bool has(const std::string& key) const { return node_ && node_.IsMap() && node_[key]; }

  // A number within [min, max]; keeps `value` when the key is absent.
  template <typename T>
  void read(const std::string& key, T& value, T min, T max) {
    used_.insert(key);
    if (!has(key)) return;
    const YAML::Node item = node_[key];
    value = number<T>(item, field(key), min, max);
  }

  // true / false; keeps `value` when the key is absent.
  void read_flag(const std::string& key, bool& value) {
    used_.insert(key);
    if (!has(key)) return;
    const YAML::Node item = node_[key];
    bool parsed = false;
    if (!item.IsScalar() || !YAML::convert<bool>::decode(item, parsed)) fail(item, field(key), "expected true or false");
    value = parsed;
  }

  // Text; std::nullopt when the key is absent.
  std::optional<std::string> read_text(const std::string& key) {
    used_.insert(key);
    if (!has(key)) return std::nullopt;
    const YAML::Node item = node_[key];
    if (!item.IsScalar()) fail(item, field(key), "expected text");
    return item.as<std::string>();
  }

  // A list of numbers within [min, max]; keeps `values` when the key is absent.
  template <typename T>
  void read_list(const std::string& key, std::vector<T>& values, T min, T max) {
    used_.insert(key);
    if (!has(key)) return;
    const YAML::Node list = node_[key];
    if (!list.IsSequence()) fail(list, field(key), "expected a list, e.g. [0, 20, 40]");
    std::vector<T> parsed;
    for (std::size_t i = 0; i < list.size(); ++i)
      parsed.push_back(number<T>(list[i], field(key) + "[" + std::to_string(i) + "]", min, max));
    values = std::move(parsed);
  }

  // A list of texts; keeps `values` when the key is absent.
  void read_text_list(const std::string& key, std::vector<std::string>& values) {
    used_.insert(key);
    if (!has(key)) return;
    const YAML::Node list = node_[key];
    if (!list.IsSequence()) fail(list, field(key), "expected a list of names");
    std::vector<std::string> parsed;
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (!list[i].IsScalar()) fail(list[i], field(key) + "[" + std::to_string(i) + "]", "expected text");
      parsed.push_back(list[i].as<std::string>());
    }
    values = std::move(parsed);
  }

  // A nested node (map or list) for the caller to read; an undefined node (false) when absent.
  YAML::Node child(const std::string& key) {
    used_.insert(key);
    return has(key) ? node_[key] : YAML::Node(YAML::NodeType::Undefined);
  }

  void reject_unknown_keys() const {
    if (!node_ || !node_.IsMap()) return;
    for (const auto& entry : node_) {
      const std::string key = entry.first.as<std::string>();
      if (!used_.contains(key)) fail(entry.first, field(key), "unknown key");
    }
  }

  std::string field(const std::string& key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
  const std::filesystem::path& file() const { return file_; }
  const YAML::Node& node() const { return node_; }

  // Fails at the value of `key` (or at the map when the key is absent).
  [[noreturn]] void fail_at(const std::string& key, const std::string& message) const {
    fail(has(key) ? node_[key] : node_, field(key), message);
  }

  [[noreturn]] void fail(const YAML::Node& at, const std::string& name, const std::string& message) const {
    throw InputError(file_, at.Mark().line + 1, "field '" + name + "': " + message);
  }

private:
  template <typename T>
  T number(const YAML::Node& item, const std::string& name, T min, T max) const {
    T parsed{};
    try {
      if (!item.IsScalar()) throw YAML::Exception(item.Mark(), "not a scalar");
      parsed = item.as<T>();
    } catch (const YAML::Exception&) {
      fail(item, name, "expected a number, got '" + YAML::Dump(item) + "'");
    }
    if (!(parsed >= min && parsed <= max))
      fail(item, name, "value " + std::to_string(parsed) + " outside [" + std::to_string(min) + ", " +
                           std::to_string(max) + "]");
    return parsed;
  }

  YAML::Node node_;
  std::filesystem::path file_;
  std::string prefix_;
  std::set<std::string> used_;
};

// Loads a YAML file; InputError naming the file (and the line of a syntax error).
inline YAML::Node load_yaml_file(const std::filesystem::path& file) {
  try {
    return YAML::LoadFile(file.string());
  } catch (const YAML::BadFile&) {
    throw InputError(file, "cannot open configuration file");
  } catch (const YAML::ParserException& e) {
    throw InputError(file, e.mark.line + 1, "not valid YAML: " + e.msg);
  }
}

}  // namespace nirslam::config_detail
