#pragma once

// Four-character codes, as V4L2 names pixel formats and the map file tags its sections.

#include <cstddef>
#include <cstdint>
#include <string>

namespace rankslam {

/// Builds a four-character code, first character in the low byte: fourcc('Y', 'U', 'Y', 'V').
constexpr std::uint32_t fourcc(char a, char b, char c, char d) {
  return static_cast<std::uint32_t>(static_cast<unsigned char>(a)) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(b)) << 8U) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(c)) << 16U) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(d)) << 24U);
}

/// A four-character code as text ("YUYV"); non-printable bytes become '?'.
[[nodiscard]] inline std::string fourcc_to_string(std::uint32_t code) {
  std::string text(4, '?');
  for (std::size_t i = 0; i < 4; ++i) {
    const auto byte = static_cast<char>((code >> (8U * i)) & 0xFFU);
    if (byte >= 0x20 && byte < 0x7F) text[i] = byte;
  }
  return text;
}

}  // namespace rankslam
