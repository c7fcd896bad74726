#pragma once

#include "rankslam/hal/interfaces.hpp"

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rankslam::socketcan {

/// Receive only data frames whose identifier matches `id` in the bits set in `mask`.
struct CanIdFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0x7FF;  ///< Identifier bits that must equal those of `id`.
  bool extended = false;       ///< Match 29-bit identifiers (otherwise 11-bit only).
};

/// Set-up of a SocketCAN bus; fixed after construction.
struct SocketCanOptions {
  /// Network interface to bind: can0, vcan0, ...
  std::string interface_name = "can0";
  /// Data frames matching any of these are received; empty = every data frame. Remote frames
  /// are never delivered. At most SocketCanBus::kMaxFilters.
  std::vector<CanIdFilter> filters;
  /// Receive the controller's error frames (bus-off, error-passive, lost arbitration, ...)
  /// and count them in the statistics.
  bool error_frames = true;
  /// After a fault, the least time between two attempts to reopen; 0 = at every call.
  std::chrono::milliseconds reopen_interval{500};
  /// Kernel receive buffer (SO_RCVBUF) in bytes; 0 keeps the kernel default.
  int receive_buffer_bytes = 0;
};

/// hal::CanBus on a Linux SocketCAN raw socket.
///
/// receive(): waits in poll() at most `wait`; wait 0 returns kNoData when nothing is queued,
/// a longer wait kTimeout. Frames carry the kernel's receive time (SO_TIMESTAMPNS, taken on
/// CLOCK_REALTIME when the frame entered the network stack) converted to CLOCK_MONOTONIC, the
/// clock of every other stamp in rankslam; the conversion uses the clocks' offset at the
/// moment of reading, so a step of the wall clock between arrival and reading shifts that one
/// frame. Error frames never reach the caller: they update statistics(), and bus-off returns
/// kFault, as does a timeout while the controller stays bus-off.
///
/// send(): never blocks. kOk = queued in the kernel; kNoData = transmit queue full (ENOBUFS
/// or EAGAIN), the frame is dropped and counted in tx_dropped, try again later; kFault = the
/// interface is down or gone, or the frame is invalid (counted in tx_invalid).
///
/// An interface that goes down (ENETDOWN) or disappears (ENODEV) makes the call return
/// kFault and closes the socket; later calls reopen it, at most once per reopen_interval,
/// once the interface exists and is up again.
///
/// One thread at a time: open a second bus on the same interface to send from another thread.
class SocketCanBus final : public hal::CanBus {
 public:
  static constexpr std::size_t kMaxFilters = 32;

  explicit SocketCanBus(SocketCanOptions options);
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  /// Opens and binds the socket. Empty on success, otherwise what went wrong.
  [[nodiscard]] std::string open() override;
  [[nodiscard]] hal::ReadStatus receive(hal::CanFrame& frame, std::chrono::milliseconds wait) override;
  [[nodiscard]] hal::ReadStatus send(const hal::CanFrame& frame) override;
  void close() override;
  [[nodiscard]] hal::CanBusStatistics statistics() const override { return statistics_; }

  [[nodiscard]] const SocketCanOptions& options() const { return options_; }
  /// True while the socket is open (false after a fault until a reopen succeeds).
  [[nodiscard]] bool is_open() const { return fd_ >= 0; }

 private:
  /// Creates, configures and binds the socket into fd_; empty on success.
  std::string open_socket();
  void close_socket();
  /// After a fault: reopens when allowed by reopen_interval; true when the socket is open.
  bool ensure_open();
  hal::ReadStatus fault();

  SocketCanOptions options_;
  int fd_ = -1;
  bool opened_ = false;  // open() succeeded and close() was not called since
  std::int64_t last_reopen_attempt_ns_ = 0;
  hal::CanBusStatistics statistics_;
};

}  // namespace rankslam::socketcan
