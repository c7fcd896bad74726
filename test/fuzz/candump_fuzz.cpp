// candump -l lines as replay reads can.log: any line parses or is refused without crashing, and
// a parsed frame survives format -> parse unchanged (to the microsecond the format keeps).
#include "fuzz_support.hpp"
#include "rankslam/hal/candump.hpp"

#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using rankslam::fuzz::require;
  const std::string_view line(reinterpret_cast<const char*>(data), size);
  const auto frame = rankslam::hal::parse_candump_line(line);
  if (!frame) return 0;
  require(frame->length <= 8, "length within 0..8");
  require(frame->id <= (frame->extended ? 0x1FFFFFFFU : 0x7FFU), "identifier within its 11 or 29 bits");
  const auto again = rankslam::hal::parse_candump_line(rankslam::hal::format_candump_line(*frame, "can0"));
  require(again.has_value(), "a formatted frame parses again");
  require(again->id == frame->id && again->extended == frame->extended && again->length == frame->length &&
              again->data == frame->data,
          "identifier and data survive a round trip");
  require(again->stamp_ns == frame->stamp_ns / 1000 * 1000, "the stamp survives a round trip to the microsecond");
  return 0;
}
