#pragma once

// Strict reading of the YAML files a user writes (configurations, calibration.yaml): one set of
// rules for all of them. Every function returns why the input is wrong, without the file's name
// (the caller prefixes it), or an empty string when it is right.

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>
#include <string>
#include <type_traits>

namespace rankslam::yaml {

/// Parses the regular file `path` into `root`. Not valid YAML (nested too deep included), a key
/// that is not a plain scalar (`? [a, b]`) or a key given twice in one map are errors naming the
/// line or the key path.
[[nodiscard]] std::string load_file(const std::filesystem::path& path, YAML::Node& root);

/// " (line L, column C)" of a node read from a file; empty for a node built in memory.
[[nodiscard]] inline std::string at(const YAML::Mark& mark) {
  if (mark.is_null()) return {};
  return " (line " + std::to_string(mark.line + 1) + ", column " + std::to_string(mark.column + 1) + ")";
}

/// Why `node`, found at `key_path` (dotted), is not a map whose keys are all in `known`:
/// "'<key_path>' must be a map" or "<key_path>.<key> is not a known <noun>" ("'<key>' is not a
/// known <noun>" at the root, key_path empty), each followed by where in the file (at()). Keys are
/// scalars: load_file checked them.
[[nodiscard]] std::string check_map(const YAML::Node& node, const std::string& key_path,
                                    const std::set<std::string>& known, const std::string& noun = "key");

/// Why `value` is not a finite number within [min, max], naming `key_path`; empty when it is.
/// Written as !(value >= min && value <= max) so that NaN fails.
template <typename T>
[[nodiscard]] std::string check_range(T value, const std::string& key_path, T min, T max) {
  static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>);
  if (value >= min && value <= max) return {};
  std::ostringstream text;
  text << key_path << " = " << value;
  if constexpr (std::is_floating_point_v<T>) {
    // NaN and infinity fail every range; say so rather than print a range they are "outside".
    if (!std::isfinite(value)) {
      text << " is not a finite number";
      return text.str();
    }
  }
  text << " is outside " << min << " .. " << max;
  return text.str();
}

/// Why the scalar `node` is not a number of type T, with where it is; empty when it is one (then
/// in `parsed`).
template <typename T>
[[nodiscard]] std::string parse_number(const YAML::Node& node, const std::string& key_path, T& parsed) {
  if (!node.IsScalar()) {
    const char* found = node.IsMap() ? "a map" : node.IsSequence() ? "a list" : "nothing";
    return key_path + " is not a valid value: expected a number, not " + found + at(node.Mark());
  }
  if (YAML::convert<T>::decode(node, parsed)) return {};
  const char* kind = std::is_floating_point_v<T> ? "a number"
                     : std::is_signed_v<T>       ? "a whole number"
                                                 : "a whole number of 0 or more";
  return key_path + " is not a valid value: '" + node.Scalar() + "' is not " + kind + at(node.Mark());
}

/// Reads the scalar `node`, found at `key_path`, as a finite number of type T within [min, max];
/// `value` is left alone when it is not one.
template <typename T>
[[nodiscard]] std::string read_number(const YAML::Node& node, const std::string& key_path, T min, T max, T& value) {
  T parsed{};
  if (auto error = parse_number(node, key_path, parsed); !error.empty()) return error;
  if (auto error = check_range(parsed, key_path, min, max); !error.empty()) return error + at(node.Mark());
  value = parsed;
  return {};
}

}  // namespace rankslam::yaml
