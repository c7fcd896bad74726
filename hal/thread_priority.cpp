#include "rankslam/hal/thread_priority.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstring>

namespace rankslam::hal {

std::string make_this_thread_realtime(int priority) {
  if (priority < 1 || priority > kMaxRealtimePriority) {
    return "priority " + std::to_string(priority) + " is outside 1 .. " + std::to_string(kMaxRealtimePriority);
  }
  sched_param param{};
  param.sched_priority = priority;
  const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (error == 0) return {};
  std::string text = "SCHED_FIFO priority " + std::to_string(priority) + ": " + std::strerror(error);
  if (error == EPERM) {
    rlimit limit{};
    const bool have_limit = getrlimit(RLIMIT_RTPRIO, &limit) == 0;
    text += " (needs CAP_SYS_NICE or RLIMIT_RTPRIO >= " + std::to_string(priority) +
            (have_limit ? ", the limit is " + std::to_string(static_cast<unsigned long long>(limit.rlim_cur)) : std::string()) +
            "; systemd: LimitRTPRIO=)";
  }
  return text;
}

}  // namespace rankslam::hal
