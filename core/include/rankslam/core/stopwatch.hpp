#pragma once

// Stage timing on the monotonic clock, written once for every part.

#include <chrono>

namespace rankslam {

using SteadyClock = std::chrono::steady_clock;

/// Milliseconds on the monotonic clock since `since`.
[[nodiscard]] inline double elapsed_ms(SteadyClock::time_point since) {
  return std::chrono::duration<double, std::milli>(SteadyClock::now() - since).count();
}

}  // namespace rankslam
