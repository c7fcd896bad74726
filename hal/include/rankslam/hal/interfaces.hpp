#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/hal/status.hpp"

#include <chrono>
#include <cstdint>
#include <string>

namespace rankslam::hal {

/// Registered colour + depth (+ IR) camera. `open()` may allocate and fail with a message;
/// `read()` never blocks longer than `wait` and never throws.
class DepthCamera {
 public:
  virtual ~DepthCamera() = default;
  /// Returns an empty string on success, otherwise what went wrong.
  [[nodiscard]] virtual std::string open() = 0;
  [[nodiscard]] virtual const Calibration& calibration() const = 0;
  /// Fills `frame` with views into a pool slot that stays valid until the next `read()`.
  [[nodiscard]] virtual ReadStatus read(RgbdFrame& frame, std::chrono::milliseconds wait) = 0;
  virtual void close() = 0;
};

/// A single camera (the wide-angle camera).
class Camera {
 public:
  virtual ~Camera() = default;
  [[nodiscard]] virtual std::string open() = 0;
  [[nodiscard]] virtual ReadStatus read(ImageFrame& frame, std::chrono::milliseconds wait) = 0;
  virtual void close() = 0;
};

/// Counters a CAN bus keeps from open() on, for health checks and the run report.
struct CanBusStatistics {
  std::uint64_t frames_rx = 0;        ///< Data frames handed to the caller.
  std::uint64_t frames_tx = 0;        ///< Frames the bus accepted for sending.
  std::uint64_t tx_dropped = 0;       ///< Frames not sent because the transmit queue was full.
  std::uint64_t tx_invalid = 0;       ///< Frames refused because identifier or length were invalid.
  std::uint64_t rx_dropped = 0;       ///< Frames lost because the receive queue was full.
  std::uint64_t error_frames = 0;     ///< Error frames received, any class.
  std::uint64_t bus_off = 0;          ///< Times the controller went bus-off.
  std::uint64_t restarts = 0;         ///< Controller restarts after bus-off.
  std::uint64_t error_warning = 0;    ///< Times the controller reached error-warning.
  std::uint64_t error_passive_entered = 0;  ///< Times the controller became error-passive.
  std::uint64_t arbitration_lost = 0; ///< Lost-arbitration reports.
  std::uint64_t controller_overflows = 0;   ///< Controller RX/TX buffer overflows.
  std::uint64_t protocol_errors = 0;  ///< Bit, stuff, form, CRC and similar violations.
  std::uint64_t no_ack = 0;           ///< Frames nobody acknowledged.
  std::uint64_t bus_errors = 0;       ///< Bus errors the controller reported without detail.
  std::uint64_t transceiver_errors = 0;
  std::uint64_t tx_timeouts = 0;      ///< Frames the controller could not send in time.
  std::uint64_t faults = 0;           ///< Calls that returned kFault (bus off, down or gone).
  std::uint64_t reopens = 0;          ///< Successful reopens after a fault.
  bool bus_off_now = false;           ///< Bus-off and not yet restarted.
  bool error_passive = false;         ///< The controller is error-passive now.
  bool error_warning_now = false;     ///< The controller is at error-warning now.
  std::uint8_t tx_error_counter = 0;  ///< Last transmit error counter the controller reported.
  std::uint8_t rx_error_counter = 0;  ///< Last receive error counter the controller reported.
};

/// A CAN bus. Frames are caller-owned; neither call blocks longer than `wait`.
class CanBus {
 public:
  virtual ~CanBus() = default;
  [[nodiscard]] virtual std::string open() = 0;
  [[nodiscard]] virtual ReadStatus receive(CanFrame& frame, std::chrono::milliseconds wait) = 0;
  [[nodiscard]] virtual ReadStatus send(const CanFrame& frame) = 0;
  virtual void close() = 0;
  /// Counters since open(); a bus that keeps none reports zeros.
  [[nodiscard]] virtual CanBusStatistics statistics() const { return {}; }
};

/// Monotonic time source, so replay can run on recorded time and tests on a manual clock.
class Clock {
 public:
  virtual ~Clock() = default;
  [[nodiscard]] virtual std::int64_t now_ns() const = 0;
};

/// The host's CLOCK_MONOTONIC.
class MonotonicClock final : public Clock {
 public:
  [[nodiscard]] std::int64_t now_ns() const override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};

}  // namespace rankslam::hal
