#pragma once

#include <chrono>
#include <cstdint>

namespace rankslam::hal {

/// A faulted driver's read(): sleeps on CLOCK_MONOTONIC until its next reopen attempt is due
/// (`last_attempt_ns` + `interval`; an interval already passed allows one attempt per read) or
/// until `deadline_ns`, whichever is first, so a caller's read loop does not spin on a dead
/// device. True when the attempt is due before the deadline (the caller makes it); false at the
/// deadline, with `reopen` off, or when a signal ended the sleep. Never allocates.
[[nodiscard]] bool sleep_until_reopen_due(std::int64_t last_attempt_ns, std::chrono::nanoseconds interval, bool reopen,
                                          std::int64_t deadline_ns);

}  // namespace rankslam::hal
