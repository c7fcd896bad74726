#include "rankslam/hal/image_header.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

namespace rankslam::hal {
namespace {

using Bytes = std::span<const unsigned char>;

bool starts_with(Bytes bytes, std::initializer_list<unsigned char> prefix) {
  return bytes.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), bytes.begin());
}

std::uint32_t big_endian(Bytes bytes, std::size_t at, std::size_t size) {
  std::uint32_t value = 0;
  for (std::size_t i = 0; i < size; ++i) value = (value << 8U) | bytes[at + i];
  return value;
}

// Positive image dimensions that fit an int, as OpenCV's Mat needs them.
std::optional<ImageHeader> valid(std::uint32_t width, std::uint32_t height, int channels, int bit_depth) {
  constexpr std::uint32_t kMaxDimension = 1U << 30U;
  if (width == 0 || height == 0 || width > kMaxDimension || height > kMaxDimension) return std::nullopt;
  return ImageHeader{static_cast<int>(width), static_cast<int>(height), channels, bit_depth};
}

std::optional<ImageHeader> png_header(Bytes bytes) {
  // Signature (8), IHDR length (4) and type (4), width (4), height (4), bit depth, colour type.
  if (bytes.size() < 26 || big_endian(bytes, 8, 4) != 13 || !std::equal(bytes.begin() + 12, bytes.begin() + 16, "IHDR")) {
    return std::nullopt;
  }
  const int bit_depth = bytes[24];
  int channels = 0;
  switch (bytes[25]) {
    case 0: channels = 1; break;  // grey
    case 2: channels = 3; break;  // RGB
    case 3: channels = 3; break;  // palette, decoded as colour
    case 4: channels = 2; break;  // grey + alpha
    case 6: channels = 4; break;  // RGB + alpha
    default: return std::nullopt;
  }
  return valid(big_endian(bytes, 16, 4), big_endian(bytes, 20, 4), channels, bit_depth);
}

std::optional<ImageHeader> jpeg_header(Bytes bytes) {
  std::size_t at = 2;
  while (at + 4 <= bytes.size()) {
    if (bytes[at] != 0xFF) return std::nullopt;
    const unsigned char marker = bytes[at + 1];
    if (marker == 0xFF) {  // fill byte
      ++at;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // segments without a length
      at += 2;
      continue;
    }
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;  // end of image or scan before any frame header
    const std::size_t length = big_endian(bytes, at + 2, 2);
    if (length < 2) return std::nullopt;
    const bool start_of_frame = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (start_of_frame) {
      // Length (2), precision (1), height (2), width (2), components (1).
      if (length < 8 || at + 10 > bytes.size()) return std::nullopt;
      return valid(big_endian(bytes, at + 7, 2), big_endian(bytes, at + 5, 2), bytes[at + 9], bytes[at + 4]);
    }
    at += 2 + length;
  }
  return std::nullopt;
}

std::optional<ImageHeader> pnm_header(Bytes bytes) {
  // "P5"/"P6", then width, height and maximum value as decimal text between blanks and comments.
  std::size_t at = 2;
  std::array<std::uint32_t, 3> values{};
  for (auto& value : values) {
    for (;;) {
      if (at >= bytes.size()) return std::nullopt;
      if (bytes[at] == '#') {
        while (at < bytes.size() && bytes[at] != '\n' && bytes[at] != '\r') ++at;
      } else if (bytes[at] == ' ' || bytes[at] == '\t' || bytes[at] == '\n' || bytes[at] == '\r' ||
                 bytes[at] == '\v' || bytes[at] == '\f') {
        ++at;
      } else {
        break;
      }
    }
    std::size_t digits = 0;
    for (; at < bytes.size() && bytes[at] >= '0' && bytes[at] <= '9'; ++at, ++digits) {
      if (digits == 9) return std::nullopt;  // beyond any sensible image size, and would overflow
      value = value * 10 + (bytes[at] - '0');
    }
    if (digits == 0) return std::nullopt;
  }
  if (values[2] == 0 || values[2] > 65535) return std::nullopt;
  return valid(values[0], values[1], bytes[1] == '5' ? 1 : 3, values[2] > 255 ? 16 : 8);
}

std::optional<ImageHeader> tiff_header(Bytes bytes) {
  const bool little = bytes[0] == 'I';
  const auto read = [&](std::size_t at, std::size_t size) -> std::optional<std::uint32_t> {
    if (at > bytes.size() || size > bytes.size() - at) return std::nullopt;
    std::uint32_t value = 0;
    for (std::size_t i = 0; i < size; ++i) {
      const std::uint32_t byte = bytes[at + (little ? size - 1 - i : i)];
      value = (value << 8U) | byte;
    }
    return value;
  };
  const auto ifd = read(4, 4);
  if (!ifd) return std::nullopt;
  const auto count = read(*ifd, 2);
  if (!count) return std::nullopt;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t bits = 1;  // the TIFF defaults
  std::uint32_t samples = 1;
  for (std::uint32_t i = 0; i < *count; ++i) {
    const std::size_t entry = *ifd + 2 + 12 * static_cast<std::size_t>(i);
    const auto tag = read(entry, 2);
    const auto type = read(entry + 2, 2);
    const auto values = read(entry + 4, 4);
    if (!tag || !type || !values) return std::nullopt;
    // SHORT (3) or LONG (4); several SHORTs that do not fit the entry are stored at an offset.
    const std::size_t size = *type == 3 ? 2 : *type == 4 ? 4 : 0;
    if (size == 0) continue;
    std::size_t value_at = entry + 8;
    if (*values * size > 4) {
      const auto offset = read(entry + 8, 4);
      if (!offset) return std::nullopt;
      value_at = *offset;
    }
    const auto value = read(value_at, size);
    if (!value) return std::nullopt;
    if (*tag == 256) width = *value;
    if (*tag == 257) height = *value;
    if (*tag == 258) bits = *value;
    if (*tag == 277) samples = *value;
  }
  if (samples == 0 || samples > 16 || bits == 0 || bits > 64) return std::nullopt;
  return valid(width, height, static_cast<int>(samples), static_cast<int>(bits));
}

}  // namespace

std::optional<ImageHeader> read_image_header(std::span<const unsigned char> bytes) {
  if (starts_with(bytes, {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'})) return png_header(bytes);
  if (starts_with(bytes, {0xFF, 0xD8, 0xFF})) return jpeg_header(bytes);
  if (starts_with(bytes, {'P', '5'}) || starts_with(bytes, {'P', '6'})) return pnm_header(bytes);
  if (starts_with(bytes, {'I', 'I', 0x2A, 0x00}) || starts_with(bytes, {'M', 'M', 0x00, 0x2A})) {
    return tiff_header(bytes);
  }
  return std::nullopt;
}

}  // namespace rankslam::hal
