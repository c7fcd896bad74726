#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <variant>

namespace rankslam::eval {

/// A value, or a message saying why there is none (std::expected is C++23).
template <typename T>
class [[nodiscard]] Result {
 public:
  static Result success(T value) { return Result(std::in_place_index<0>, std::move(value)); }
  static Result failure(std::string message) {
    return Result(std::in_place_index<1>, std::move(message));
  }

  [[nodiscard]] bool ok() const { return state_.index() == 0; }
  explicit operator bool() const { return ok(); }

  /// Only valid when ok(); otherwise throws std::bad_variant_access (a programming error).
  [[nodiscard]] const T& value() const& { return std::get<0>(state_); }
  [[nodiscard]] T& value() & { return std::get<0>(state_); }
  [[nodiscard]] T&& value() && { return std::get<0>(std::move(state_)); }

  /// The failure message; empty when ok().
  [[nodiscard]] const std::string& error() const {
    static const std::string kNone;
    return ok() ? kNone : std::get<1>(state_);
  }

 private:
  template <std::size_t kIndex, typename Arg>
  Result(std::in_place_index_t<kIndex> tag, Arg&& arg) : state_(tag, std::forward<Arg>(arg)) {}

  std::variant<T, std::string> state_;
};

}  // namespace rankslam::eval
