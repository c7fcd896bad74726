#include "rankslam/hal/thread_priority.hpp"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <string>
#include <thread>

namespace rankslam::hal {
namespace {

// Runs make_this_thread_realtime on a thread of its own, so the test runner keeps its scheduling.
struct Outcome {
  std::string error;
  int policy = -1;
  int priority = -1;
};

Outcome on_own_thread(int priority) {
  Outcome outcome;
  std::thread([&] {
    outcome.error = make_this_thread_realtime(priority);
    sched_param param{};
    pthread_getschedparam(pthread_self(), &outcome.policy, &param);
    outcome.priority = param.sched_priority;
  }).join();
  return outcome;
}

TEST(ThreadPriority, RefusesPrioritiesOutsideTheRangeAndKeepsTheScheduling) {
  for (const int priority : {0, -3, kMaxRealtimePriority + 1, 99}) {
    const Outcome outcome = on_own_thread(priority);
    EXPECT_NE(outcome.error.find("outside 1 .. " + std::to_string(kMaxRealtimePriority)), std::string::npos) << outcome.error;
    EXPECT_EQ(outcome.policy, SCHED_OTHER);
  }
}

TEST(ThreadPriority, RunsUnderFifoOrSaysWhatPermissionIsMissing) {
  const Outcome outcome = on_own_thread(3);
  if (outcome.error.empty()) {
    EXPECT_EQ(outcome.policy, SCHED_FIFO);
    EXPECT_EQ(outcome.priority, 3);
  } else {
    // Without CAP_SYS_NICE and RLIMIT_RTPRIO: the reason and the remedy, scheduling unchanged.
    EXPECT_NE(outcome.error.find("RLIMIT_RTPRIO >= 3"), std::string::npos) << outcome.error;
    EXPECT_NE(outcome.error.find("LimitRTPRIO="), std::string::npos) << outcome.error;
    EXPECT_EQ(outcome.policy, SCHED_OTHER);
  }
}

}  // namespace
}  // namespace rankslam::hal
