#pragma once

#include <string>

namespace rankslam::hal {

/// Highest SCHED_FIFO priority a configuration may ask for; above it run the kernel's own
/// interrupt threads (50), which the CAN controller and the USB camera need.
inline constexpr int kMaxRealtimePriority = 49;

/// Puts the calling thread under SCHED_FIFO at `priority` (1 .. kMaxRealtimePriority), so
/// ordinary processes on a loaded CPU cannot delay it. Empty on success, else why not (not
/// permitted: needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at least `priority`); the thread then
/// keeps its scheduling.
[[nodiscard]] std::string make_this_thread_realtime(int priority);

}  // namespace rankslam::hal
