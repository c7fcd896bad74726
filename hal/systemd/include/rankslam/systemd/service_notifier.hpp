#pragma once

#include <cstdint>

namespace rankslam::systemd {

/// Tells the service manager how a Type=notify service is doing (sd_notify): READY=1 when its
/// loop starts, WATCHDOG=1 while that loop goes round, STOPPING=1 when it stops. Outside systemd
/// (no NOTIFY_SOCKET) every call does nothing. Only the thread that owns the loop calls it.
///
/// The watchdog is fed by whoever calls alive(): the loop calls it once per turn, whether or not
/// the camera delivered, so a silent camera (the loop waits on read() with a timeout) keeps the
/// watchdog fed and only a loop that stops going round lets WatchdogSec= expire.
class ServiceNotifier {
 public:
  /// Reads NOTIFY_SOCKET and the watchdog interval (sd_watchdog_enabled: WATCHDOG_USEC, for this
  /// process when WATCHDOG_PID is set). The environment is left as it is.
  ServiceNotifier();

  /// NOTIFY_SOCKET names a socket to notify.
  [[nodiscard]] bool active() const { return active_; }
  /// WATCHDOG=1 is sent at most once per this period, half the watchdog interval; 0: no watchdog.
  [[nodiscard]] std::int64_t watchdog_period_ns() const { return watchdog_period_ns_; }

  /// READY=1: set-up is done and the loop starts; the next WATCHDOG=1 is due a period after `now_ns`.
  void ready(std::int64_t now_ns);
  /// The loop went round at `now_ns` (CLOCK_MONOTONIC): WATCHDOG=1 when a period has passed since
  /// the last one (or READY=1). Allocates nothing; a turn without a notification is one compare.
  void alive(std::int64_t now_ns);
  /// STOPPING=1: the loop has ended; the outputs are written next.
  void stopping();

  /// WATCHDOG=1 notifications sent; notifications of any kind that sd_notify could not send.
  [[nodiscard]] std::uint64_t watchdog_sent() const { return watchdog_sent_; }
  [[nodiscard]] std::uint64_t failures() const { return failures_; }

 private:
  void send(const char* state, std::uint64_t* sent);

  bool active_ = false;
  std::int64_t watchdog_period_ns_ = 0;
  std::int64_t last_watchdog_ns_ = 0;
  std::uint64_t watchdog_sent_ = 0;
  std::uint64_t failures_ = 0;
};

}  // namespace rankslam::systemd
