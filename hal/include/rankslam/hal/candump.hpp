#pragma once

#include "rankslam/hal/messages.hpp"

#include <optional>
#include <string>
#include <string_view>

namespace rankslam::hal {

/// One line of a `candump -l` log: "(1700000000.123456) can0 101#0011223344556677".
/// Identifiers of three hex digits are standard, of eight extended. Returns nullopt for a line
/// that is not a well-formed classic CAN frame (remote and FD frames included) or whose stamp is
/// negative or does not fit an int64 of nanoseconds.
[[nodiscard]] std::optional<CanFrame> parse_candump_line(std::string_view line);

/// Formats `frame` as a `candump -l` line (without newline) on `interface_name`.
[[nodiscard]] std::string format_candump_line(const CanFrame& frame, std::string_view interface_name);

}  // namespace rankslam::hal
