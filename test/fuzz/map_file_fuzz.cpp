// The map file as slam::decode_map reads it (SlamLoop::load_map): loaded into a tiny map's
// slots or refused with a message naming the file, never a crash; a refusal leaves the store and
// graph empty; an accepted map re-encodes to a fixed point after one round trip. Each input is
// also read with its checksums made right (and its calibration digest expected), so that the
// fuzzer reaches the section decoders behind the CRCs. Seed: corpus/map_file/tiny.map, written
// by test_map_file with RANKSLAM_WRITE_MAP_SEED=<file>.
#include "fuzz_support.hpp"
#include "rankslam/slam/map_file.hpp"
#include "tiny_map.hpp"

#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace {

using rankslam::fuzz::require;
using rankslam::slam::MapDigests;

std::uint64_t get(const std::vector<unsigned char>& b, std::size_t at, std::size_t n) {
  std::uint64_t value = 0;
  for (std::size_t i = 0; i < n; ++i) value |= static_cast<std::uint64_t>(b[at + i]) << (8U * i);
  return value;
}

void put(std::vector<unsigned char>& b, std::size_t at, std::uint64_t value, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) b[at + i] = static_cast<unsigned char>(value >> (8U * i));
}

std::uint32_t crc(const std::vector<unsigned char>& b, std::size_t from, std::size_t to) {
  return static_cast<std::uint32_t>(::crc32(0L, b.data() + from, static_cast<uInt>(to - from)));
}

/// The input with its file size, header CRC, section CRCs and file CRC made right where its
/// framing allows (the layout of docs/map-format.md).
std::vector<unsigned char> resealed(std::vector<unsigned char> b) {
  if (b.size() < 30) return b;
  const std::size_t header = 30 + get(b, 28, 2);
  if (b.size() < header + 8) return b;
  put(b, 12, b.size(), 8);
  put(b, header, crc(b, 0, header), 4);
  const std::size_t end = b.size() - 4;
  for (std::size_t at = header + 4; end - at >= 16;) {
    const std::uint64_t length = get(b, at + 4, 8);
    if (length > end - at - 16) break;
    put(b, at + 12 + length, crc(b, at, at + 12 + length), 4);
    at += 16 + length;
  }
  put(b, end, crc(b, 0, end), 4);
  return b;
}

/// Loads `bytes`; on success checks the round trip's fixed point.
void check(const std::vector<unsigned char>& bytes, const MapDigests& expected) {
  rankslam::test_support::TinyMap map;
  try {
    (void)rankslam::slam::decode_map(bytes, "fuzz.map", expected, {map.store, map.graph, map.threshold});
  } catch (const std::runtime_error& error) {
    require(std::string_view(error.what()).starts_with("map file fuzz.map: "), "a refusal names the file");
    require(map.store.size() == 0 && map.graph.node_count() == 0, "a refusal leaves the map empty");
    return;
  }
  std::vector<unsigned char> once;
  rankslam::slam::encode_map(map.store, map.graph, map.threshold, expected, once);
  rankslam::test_support::TinyMap again;
  (void)rankslam::slam::decode_map(once, "again.map", expected, {again.store, again.graph, again.threshold});
  std::vector<unsigned char> twice;
  rankslam::slam::encode_map(again.store, again.graph, again.threshold, expected, twice);
  require(once == twice, "an accepted map re-encodes to a fixed point");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<unsigned char> bytes(data, data + size);
  check(bytes, {0x1234ABCDU, 0});
  const std::vector<unsigned char> sealed = resealed(bytes);
  check(sealed, {sealed.size() >= 24 ? static_cast<std::uint32_t>(get(sealed, 20, 4)) : 0U, 0});
  return 0;
}
