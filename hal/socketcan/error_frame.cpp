#include "rankslam/socketcan/error_frame.hpp"

#include <linux/can.h>
#include <linux/can/error.h>

namespace rankslam::socketcan {

ErrorFrameEffect apply_error_frame(std::uint32_t can_id, const std::array<std::uint8_t, 8>& data,
                                   hal::CanBusStatistics& statistics) {
  ErrorFrameEffect effect;
  auto& s = statistics;
  const std::uint32_t classes = can_id & CAN_ERR_MASK;
  ++s.error_frames;
  if ((classes & CAN_ERR_TX_TIMEOUT) != 0) ++s.tx_timeouts;
  if ((classes & CAN_ERR_LOSTARB) != 0) ++s.arbitration_lost;
  if ((classes & CAN_ERR_PROT) != 0) ++s.protocol_errors;
  if ((classes & CAN_ERR_TRX) != 0) ++s.transceiver_errors;
  if ((classes & CAN_ERR_ACK) != 0) ++s.no_ack;
  if ((classes & CAN_ERR_BUSERROR) != 0) ++s.bus_errors;
  if ((classes & CAN_ERR_CRTL) != 0) {
    const std::uint8_t controller = data[1];
    if ((controller & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) != 0) ++s.controller_overflows;
    // The kernel reports the one state the controller moved to (can_change_state()), upwards
    // or downwards; overflow-only reports carry no state.
    if ((controller & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0) {
      if (!s.error_passive) ++s.error_passive_entered;
      s.error_passive = true;
      s.error_warning_now = true;
    } else if ((controller & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0) {
      if (!s.error_warning_now) ++s.error_warning;
      s.error_warning_now = true;
      s.error_passive = false;
    } else if ((controller & CAN_ERR_CRTL_ACTIVE) != 0) {
      s.error_warning_now = false;
      s.error_passive = false;
    }
  }
  if ((classes & CAN_ERR_CNT) != 0) {
    s.tx_error_counter = data[6];
    s.rx_error_counter = data[7];
  }
  if ((classes & CAN_ERR_BUSOFF) != 0) {
    if (!s.bus_off_now) ++s.bus_off;
    s.bus_off_now = true;
    effect.bus_off = true;
  }
  if ((classes & CAN_ERR_RESTARTED) != 0) {
    ++s.restarts;
    s.bus_off_now = false;
    s.error_passive = false;
    s.error_warning_now = false;
    effect.restarted = true;
  }
  return effect;
}

}  // namespace rankslam::socketcan
