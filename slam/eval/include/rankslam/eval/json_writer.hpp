#pragma once

#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>

namespace rankslam::eval {

/// `value` as a JSON number, as `std::ostream <<` prints it, or null when it is not finite:
/// JSON has no nan or inf (for members formatted outside JsonWriter, see raw_object).
template <typename T>
[[nodiscard]] std::string json_number(T value) {
  static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>);
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(value)) return "null";
  }
  std::ostringstream text;
  text << value;
  return text.str();
}

/// Minimal JSON object writer for report.json: keys in insertion order, numbers printed with
/// enough digits to round-trip, non-finite numbers and empty optionals as null.
class JsonWriter {
 public:
  JsonWriter& begin_object(std::string_view key = {}) {
    separator_and_key(key);
    text_ += '{';
    first_ = true;
    return *this;
  }
  JsonWriter& end_object() {
    text_ += '}';
    first_ = false;
    return *this;
  }
  JsonWriter& number(std::string_view key, double value) {
    separator_and_key(key);
    if (!std::isfinite(value)) {
      text_ += "null";
    } else {
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "%.9g", value);
      text_ += buffer;
    }
    return *this;
  }
  JsonWriter& number(std::string_view key, std::optional<double> value) {
    return value ? number(key, *value) : null(key);
  }
  JsonWriter& integer(std::string_view key, long long value) {
    separator_and_key(key);
    text_ += std::to_string(value);
    return *this;
  }
  JsonWriter& string(std::string_view key, std::string_view value) {
    separator_and_key(key);
    quote(value);
    return *this;
  }
  JsonWriter& boolean(std::string_view key, bool value) {
    separator_and_key(key);
    text_ += value ? "true" : "false";
    return *this;
  }
  JsonWriter& null(std::string_view key) {
    separator_and_key(key);
    text_ += "null";
    return *this;
  }
  /// Inserts already-formatted JSON members (`"a": 1, "b": 2`) as an object under `key`; their
  /// numbers must be finite or null (json_number).
  JsonWriter& raw_object(std::string_view key, std::string_view members) {
    separator_and_key(key);
    text_ += '{';
    text_ += members;
    text_ += '}';
    return *this;
  }
  [[nodiscard]] std::string str() const { return text_ + "\n"; }

 private:
  void separator_and_key(std::string_view key) {
    if (!first_) text_ += ", ";
    first_ = false;
    if (!key.empty()) {
      quote(key);
      text_ += ": ";
    }
  }
  void quote(std::string_view value) {
    text_ += '"';
    for (const char c : value) {
      switch (c) {
        case '"': text_ += "\\\""; break;
        case '\\': text_ += "\\\\"; break;
        case '\n': text_ += "\\n"; break;
        case '\t': text_ += "\\t"; break;
        default:
          if (static_cast<unsigned char>(c) < 0x20) {
            char buffer[8];
            std::snprintf(buffer, sizeof buffer, "\\u%04x", static_cast<unsigned>(c));
            text_ += buffer;
          } else {
            text_ += c;
          }
      }
    }
    text_ += '"';
  }

  std::string text_;
  bool first_ = true;
};

}  // namespace rankslam::eval
