#include "rankslam/hal/reopen_wait.hpp"

#include "rankslam/hal/interfaces.hpp"

#include <time.h>

#include <algorithm>

namespace rankslam::hal {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;

}  // namespace

bool sleep_until_reopen_due(std::int64_t last_attempt_ns, std::chrono::nanoseconds interval, bool reopen,
                            std::int64_t deadline_ns) {
  // MonotonicClock is steady_clock, CLOCK_MONOTONIC on Linux: the clock the sleep below uses.
  const std::int64_t now = MonotonicClock{}.now_ns();
  if (now >= deadline_ns) return false;
  std::int64_t due_ns = reopen ? last_attempt_ns + interval.count() : deadline_ns;
  // An attempt that failed just now with a zero (or shorter than itself) interval: one per read.
  if (due_ns <= now) due_ns = deadline_ns;
  const std::int64_t until_ns = std::min(due_ns, deadline_ns);
  const timespec until{.tv_sec = until_ns / kNsPerS, .tv_nsec = until_ns % kNsPerS};
  if (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &until, nullptr) != 0) return false;
  return due_ns < deadline_ns;
}

}  // namespace rankslam::hal
