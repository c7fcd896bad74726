#pragma once

#include <cstdint>
#include <string_view>

namespace rankslam::hal {

/// Result of a non-blocking read from a sensor or bus. The loop branches on it; it never throws.
enum class ReadStatus : std::uint8_t {
  kOk,          ///< A new message was written to the caller's buffer.
  kNoData,      ///< Nothing new yet; try again next cycle.
  kTimeout,     ///< Nothing arrived within the caller's wait budget.
  kEndOfStream, ///< A recording has no more data (replay only).
  kFault,       ///< The device is gone or broken; the driver may recover on its own.
};

constexpr std::string_view to_string(ReadStatus status) {
  switch (status) {
    case ReadStatus::kOk: return "ok";
    case ReadStatus::kNoData: return "no-data";
    case ReadStatus::kTimeout: return "timeout";
    case ReadStatus::kEndOfStream: return "end-of-stream";
    case ReadStatus::kFault: return "fault";
  }
  return "unknown";
}

}  // namespace rankslam::hal
