#pragma once

#include "rankslam/hal/interfaces.hpp"

#include <array>
#include <cstdint>

namespace rankslam::socketcan {

/// What an error frame changed, beyond the counters.
struct ErrorFrameEffect {
  bool bus_off = false;    ///< The controller went bus-off.
  bool restarted = false;  ///< The controller restarted after bus-off.
};

/// Folds one SocketCAN error frame into `statistics`: `can_id` holds the error classes
/// (CAN_ERR_* of linux/can/error.h, flag bits allowed), `data` their details (data[1]
/// controller state, data[2..3] protocol violation, data[4] transceiver, data[6..7] error
/// counters). Counts transitions, not repeated reports of the same state.
ErrorFrameEffect apply_error_frame(std::uint32_t can_id, const std::array<std::uint8_t, 8>& data,
                                   hal::CanBusStatistics& statistics);

}  // namespace rankslam::socketcan
