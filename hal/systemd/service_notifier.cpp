#include "rankslam/systemd/service_notifier.hpp"

#include <systemd/sd-daemon.h>

#include <cstdlib>

namespace rankslam::systemd {

ServiceNotifier::ServiceNotifier() {
  const char* socket = std::getenv("NOTIFY_SOCKET");
  active_ = socket != nullptr && socket[0] != '\0';
  std::uint64_t usec = 0;
  if (active_ && sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    watchdog_period_ns_ = static_cast<std::int64_t>(usec) * 1000 / 2;
  }
}

void ServiceNotifier::send(const char* state, std::uint64_t* sent) {
  if (!active_) return;
  // sd_notify: a datagram on a socket made for the call; > 0 when sent.
  if (sd_notify(0, state) > 0) {
    if (sent != nullptr) ++*sent;
  } else {
    ++failures_;
  }
}

void ServiceNotifier::ready(std::int64_t now_ns) {
  send("READY=1", nullptr);
  last_watchdog_ns_ = now_ns;
}

void ServiceNotifier::alive(std::int64_t now_ns) {
  if (watchdog_period_ns_ == 0 || now_ns - last_watchdog_ns_ < watchdog_period_ns_) return;
  last_watchdog_ns_ = now_ns;
  send("WATCHDOG=1", &watchdog_sent_);
}

void ServiceNotifier::stopping() { send("STOPPING=1", nullptr); }

}  // namespace rankslam::systemd
