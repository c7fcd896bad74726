#include "rankslam/hal/reopen_wait.hpp"

#include "rankslam/hal/interfaces.hpp"

#include <gtest/gtest.h>

#include <chrono>

namespace rankslam::hal {
namespace {

using namespace std::chrono_literals;

std::int64_t now_ns() { return MonotonicClock{}.now_ns(); }
constexpr std::int64_t kMs = 1'000'000;

TEST(ReopenWait, AnAttemptDueBeforeTheDeadlineIsMadeAfterSleepingUntilIt) {
  const std::int64_t last = now_ns();
  EXPECT_TRUE(sleep_until_reopen_due(last, 20ms, true, last + 2000 * kMs));
  EXPECT_GE(now_ns(), last + 20 * kMs);  // slept until the attempt was due, not spun through
}

TEST(ReopenWait, AnAttemptDueAfterTheDeadlineWaitsOutTheDeadline) {
  const std::int64_t start = now_ns();
  EXPECT_FALSE(sleep_until_reopen_due(start, 1000ms, true, start + 30 * kMs));
  EXPECT_GE(now_ns(), start + 30 * kMs);
}

TEST(ReopenWait, WithoutReopeningOrWithAnIntervalPassedItWaitsOutTheDeadline) {
  std::int64_t start = now_ns();
  EXPECT_FALSE(sleep_until_reopen_due(start, 0ms, false, start + 30 * kMs));
  EXPECT_GE(now_ns(), start + 30 * kMs);
  // The last attempt failed just now with a zero interval: one attempt per read, the next read's.
  start = now_ns();
  EXPECT_FALSE(sleep_until_reopen_due(start, 0ms, true, start + 30 * kMs));
  EXPECT_GE(now_ns(), start + 30 * kMs);
}

TEST(ReopenWait, APassedDeadlineReturnsAtOnce) {
  const std::int64_t start = now_ns();
  EXPECT_FALSE(sleep_until_reopen_due(start - 10 * kMs, 1ms, true, start - 1));
}

}  // namespace
}  // namespace rankslam::hal
