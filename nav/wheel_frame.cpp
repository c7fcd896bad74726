#include "rankslam/nav/wheel_frame.hpp"

#include <cinttypes>
#include <cstdio>

namespace rankslam::nav {
namespace {

void put_u24(std::uint8_t* out, std::uint32_t value) {
  out[0] = static_cast<std::uint8_t>(value & 0xFFU);
  out[1] = static_cast<std::uint8_t>((value >> 8U) & 0xFFU);
  out[2] = static_cast<std::uint8_t>((value >> 16U) & 0xFFU);
}

std::uint32_t get_u24(const std::uint8_t* in) {
  return static_cast<std::uint32_t>(in[0]) | (static_cast<std::uint32_t>(in[1]) << 8U) |
         (static_cast<std::uint32_t>(in[2]) << 16U);
}

}  // namespace

hal::CanFrame encode_wheel_ticks(const WheelTicks& ticks, std::uint32_t can_id, std::int64_t stamp_ns) {
  hal::CanFrame frame;
  frame.stamp_ns = stamp_ns;
  frame.id = can_id;
  frame.length = kWheelTicksLength;
  put_u24(&frame.data[0], ticks.left_ticks % kWheelTickModulus);
  put_u24(&frame.data[3], ticks.right_ticks % kWheelTickModulus);
  frame.data[6] = ticks.rolling_counter;
  frame.data[7] = static_cast<std::uint8_t>((ticks.left_fault ? 1U : 0U) | (ticks.right_fault ? 2U : 0U));
  return frame;
}

std::optional<WheelTicks> decode_wheel_ticks(const hal::CanFrame& frame) {
  if (frame.length != kWheelTicksLength) return std::nullopt;
  WheelTicks ticks;
  ticks.left_ticks = get_u24(&frame.data[0]);
  ticks.right_ticks = get_u24(&frame.data[3]);
  ticks.rolling_counter = frame.data[6];
  ticks.left_fault = (frame.data[7] & 1U) != 0;
  ticks.right_fault = (frame.data[7] & 2U) != 0;
  return ticks;
}

std::string describe_malformed_wheel_frames(std::span<const hal::CanFrame> frames, std::uint32_t can_id) {
  constexpr std::size_t kNamed = 3;
  std::size_t count = 0;
  std::string named;
  for (const hal::CanFrame& frame : frames) {
    if (frame.id != can_id || frame.extended || frame.length == kWheelTicksLength) continue;
    if (++count > kNamed) continue;
    char text[96];
    std::snprintf(text, sizeof text, "%s%" PRId64 ".%06" PRId64 " s with %u bytes", named.empty() ? "" : ", ",
                  frame.stamp_ns / 1'000'000'000, (frame.stamp_ns % 1'000'000'000) / 1000, unsigned{frame.length});
    named += text;
  }
  if (count == 0) return {};
  char head[96];
  std::snprintf(head, sizeof head, "%zu wheel frames (identifier 0x%X) are not %u bytes long and are not used: ", count,
                can_id, unsigned{kWheelTicksLength});
  return head + named + (count > kNamed ? ", ..." : "");
}

}  // namespace rankslam::nav
