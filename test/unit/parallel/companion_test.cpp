#include "rankslam/parallel/companion.hpp"

#include <atomic>
#include <thread>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"

namespace rankslam::parallel {
namespace {

TEST(Companion, WithoutStartTheTaskRunsOnTheCallerInsideLaunch) {
  Companion companion;
  std::thread::id ran_on;
  auto task = [&] { ran_on = std::this_thread::get_id(); };
  companion.launch(task);
  EXPECT_EQ(ran_on, std::this_thread::get_id());
  companion.wait();  // nothing to wait for
}

// The task runs on the companion while the caller works; wait() returns only after it is done.
TEST(Companion, RunsTheTaskBesideTheCallerAndWaitReturnsWhenItIsDone) {
  Companion companion;
  ASSERT_EQ(companion.start(), "");
  for (int round = 0; round < 200; ++round) {
    std::atomic<bool> caller_done{false};
    std::atomic<bool> overlapped{false};
    std::thread::id ran_on;
    int result = 0;
    auto task = [&] {
      ran_on = std::this_thread::get_id();
      // Waits (bounded) for the caller's own work, which only overlapping threads can see.
      for (int spin = 0; spin < 1'000'000 && !caller_done.load(); ++spin) std::this_thread::yield();
      overlapped = caller_done.load();
      result = round + 1;
    };
    companion.launch(task);
    caller_done = true;
    companion.wait();
    ASSERT_EQ(result, round + 1) << "round " << round;
    ASSERT_NE(ran_on, std::this_thread::get_id());
    ASSERT_TRUE(overlapped) << "round " << round;
  }
}

TEST(Companion, HandingTasksOverAllocatesNothingAfterStart) {
  Companion companion;
  ASSERT_EQ(companion.start(), "");
  long sum = 0;
  auto task = [&] { sum += 1; };
  companion.launch(task);  // first hand-over outside the count
  companion.wait();
  test_support::CountAllocations count;
  for (int round = 0; round < 500; ++round) {
    companion.launch(task);
    companion.wait();
  }
  EXPECT_EQ(count.allocations(), 0);
  EXPECT_EQ(sum, 501);
}

}  // namespace
}  // namespace rankslam::parallel
