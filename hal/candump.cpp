#include "rankslam/hal/candump.hpp"

#include <charconv>
#include <cinttypes>
#include <cstdio>
#include <limits>

namespace rankslam::hal {
namespace {

std::optional<unsigned> hex_digit(char c) {
  if (c >= '0' && c <= '9') return static_cast<unsigned>(c - '0');
  if (c >= 'a' && c <= 'f') return static_cast<unsigned>(c - 'a' + 10);
  if (c >= 'A' && c <= 'F') return static_cast<unsigned>(c - 'A' + 10);
  return std::nullopt;
}

}  // namespace

std::optional<CanFrame> parse_candump_line(std::string_view line) {
  // "(" seconds "." micro ")" space interface space id "#" data
  if (line.size() < 4 || line.front() != '(') return std::nullopt;
  const auto close = line.find(')');
  const auto dot = line.find('.');
  if (close == std::string_view::npos || dot == std::string_view::npos || dot > close) return std::nullopt;
  std::int64_t seconds = 0;
  std::int64_t fraction = 0;
  const auto sec_text = line.substr(1, dot - 1);
  const auto frac_text = line.substr(dot + 1, close - dot - 1);
  if (frac_text.empty() || frac_text.size() > 9) return std::nullopt;
  // Each number must be the whole field: "(12x.5)" is no stamp.
  const auto parse_all = [](std::string_view text, std::int64_t& value) {
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    return ec == std::errc{} && end == text.data() + text.size();
  };
  if (!parse_all(sec_text, seconds) || !parse_all(frac_text, fraction)) return std::nullopt;
  for (std::size_t i = frac_text.size(); i < 9; ++i) fraction *= 10;
  // candump stamps are never negative; a stamp whose nanoseconds overflow an int64 is no stamp.
  if (sec_text.empty() || sec_text.front() == '-' || fraction < 0 ||
      seconds > (std::numeric_limits<std::int64_t>::max() - fraction) / 1'000'000'000) {
    return std::nullopt;
  }

  auto rest = line.substr(close + 1);
  const auto iface_start = rest.find_first_not_of(' ');
  if (iface_start == std::string_view::npos) return std::nullopt;
  rest = rest.substr(iface_start);
  const auto iface_end = rest.find(' ');
  if (iface_end == std::string_view::npos) return std::nullopt;
  rest = rest.substr(iface_end + 1);
  while (!rest.empty() && (rest.back() == '\r' || rest.back() == ' ' || rest.back() == '\n')) {
    rest.remove_suffix(1);
  }
  const auto hash = rest.find('#');
  if (hash == std::string_view::npos || (hash != 3 && hash != 8)) return std::nullopt;

  CanFrame frame;
  frame.stamp_ns = seconds * 1'000'000'000 + fraction;
  frame.extended = hash == 8;
  for (std::size_t i = 0; i < hash; ++i) {
    const auto digit = hex_digit(rest[i]);
    if (!digit) return std::nullopt;
    frame.id = (frame.id << 4U) | *digit;
  }
  // Three hex digits reach 0xFFF and eight 0xFFFFFFFF: beyond the 11 and 29 bits of a CAN identifier.
  if (frame.id > (frame.extended ? 0x1FFFFFFFU : 0x7FFU)) return std::nullopt;
  const auto data = rest.substr(hash + 1);
  if (data.size() % 2 != 0 || data.size() > 16) return std::nullopt;
  frame.length = static_cast<std::uint8_t>(data.size() / 2);
  for (std::size_t i = 0; i < frame.length; ++i) {
    const auto hi = hex_digit(data[2 * i]);
    const auto lo = hex_digit(data[2 * i + 1]);
    if (!hi || !lo) return std::nullopt;
    frame.data[i] = static_cast<std::uint8_t>((*hi << 4U) | *lo);
  }
  return frame;
}

std::string format_candump_line(const CanFrame& frame, std::string_view interface_name) {
  char head[64];
  const std::int64_t seconds = frame.stamp_ns / 1'000'000'000;
  const std::int64_t micros = (frame.stamp_ns % 1'000'000'000) / 1000;
  std::snprintf(head, sizeof head, "(%" PRId64 ".%06" PRId64 ") ", seconds, micros);
  std::string line = head;
  line += interface_name;
  char id[16];
  std::snprintf(id, sizeof id, frame.extended ? " %08X#" : " %03X#", frame.id);
  line += id;
  static constexpr char kHex[] = "0123456789ABCDEF";
  for (std::size_t i = 0; i < frame.length && i < frame.data.size(); ++i) {
    line += kHex[frame.data[i] >> 4U];
    line += kHex[frame.data[i] & 0xFU];
  }
  return line;
}

}  // namespace rankslam::hal
