#pragma once

#include "rankslam/hal/messages.hpp"

#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace rankslam::nav {

/// Wheel encoder frame `WheelTicks` (deploy/can/rankslam.dbc), sent by the base controller.
/// Layout, little-endian:
///   bytes 0..2  left wheel tick counter, unsigned 24 bit, wraps at 2^24
///   bytes 3..5  right wheel tick counter, unsigned 24 bit, wraps at 2^24
///   byte  6     rolling counter, increments by one per frame, wraps at 256
///   byte  7     status bits: bit 0 left encoder fault, bit 1 right encoder fault
struct WheelTicks {
  std::uint32_t left_ticks = 0;   ///< 0 .. 2^24 - 1
  std::uint32_t right_ticks = 0;  ///< 0 .. 2^24 - 1
  std::uint8_t rolling_counter = 0;
  bool left_fault = false;
  bool right_fault = false;
};

inline constexpr std::uint32_t kWheelTickModulus = 1U << 24;
inline constexpr std::uint8_t kWheelTicksLength = 8;

/// Encodes `ticks` (counters taken modulo 2^24) into a frame with identifier `can_id`.
[[nodiscard]] hal::CanFrame encode_wheel_ticks(const WheelTicks& ticks, std::uint32_t can_id,
                                               std::int64_t stamp_ns);

/// Decodes a `WheelTicks` frame; nullopt when the length is wrong.
[[nodiscard]] std::optional<WheelTicks> decode_wheel_ticks(const hal::CanFrame& frame);

/// Frames of `frames` with the wheel identifier `can_id` (standard) whose length is not
/// kWheelTicksLength: they cannot be decoded, and the odometry counts them as malformed. An empty
/// string when there are none, otherwise their number and the first few (stamp and length).
[[nodiscard]] std::string describe_malformed_wheel_frames(std::span<const hal::CanFrame> frames, std::uint32_t can_id);

/// Signed tick difference `current - previous` across a 24-bit wrap (|delta| < 2^23).
[[nodiscard]] constexpr std::int32_t wheel_tick_delta(std::uint32_t previous, std::uint32_t current) {
  const std::uint32_t raw = (current - previous) & (kWheelTickModulus - 1);
  return raw >= kWheelTickModulus / 2 ? static_cast<std::int32_t>(raw) - static_cast<std::int32_t>(kWheelTickModulus)
                                      : static_cast<std::int32_t>(raw);
}

}  // namespace rankslam::nav
