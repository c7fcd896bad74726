#include "rankslam/parallel/companion.hpp"

#include <atomic>
#include <cstdio>
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
    std::atomic<bool> started{false};
    std::atomic<bool> caller_done{false};
    std::atomic<bool> overlapped{false};
    std::thread::id ran_on;
    int result = 0;
    auto task = [&] {
      ran_on = std::this_thread::get_id();
      started = true;
      // Waits (bounded) for the caller's own work, which only overlapping threads can see.
      for (int spin = 0; spin < 1'000'000 && !caller_done.load(); ++spin) std::this_thread::yield();
      overlapped = caller_done.load();
      result = round + 1;
    };
    companion.launch(task);
    // The caller's own work lasts until the companion has picked the task up (bounded: a task
    // still waiting at wait() runs on the caller, which the thread check below would catch).
    for (int spin = 0; spin < 10'000'000 && !started.load(); ++spin) std::this_thread::yield();
    caller_done = true;
    companion.wait();
    ASSERT_EQ(result, round + 1) << "round " << round;
    ASSERT_NE(ran_on, std::this_thread::get_id()) << "round " << round;
    ASSERT_TRUE(overlapped) << "round " << round;
  }
}

// idle() tells a task under way from a finished one without waiting, and never runs it itself.
TEST(Companion, IdleTellsWhetherTheTaskHasFinishedWithoutWaitingForIt) {
  Companion companion;
  EXPECT_TRUE(companion.idle()) << "not started: tasks run inside launch()";
  ASSERT_EQ(companion.start(), "");
  EXPECT_TRUE(companion.idle()) << "nothing launched";
  std::atomic<bool> release{false};
  std::thread::id ran_on;
  auto task = [&] {
    ran_on = std::this_thread::get_id();
    while (!release.load()) std::this_thread::yield();
  };
  companion.launch(task);
  for (int i = 0; i < 100; ++i) EXPECT_FALSE(companion.idle());
  release = true;
  while (!companion.idle()) std::this_thread::yield();
  companion.wait();
  EXPECT_NE(ran_on, std::this_thread::get_id());
}

// A caller that waits at once takes the task over when the companion has not started it; either
// way every task runs exactly once and wait() returns after it.
TEST(Companion, EveryTaskRunsOnceWhoeverRunsIt) {
  Companion companion;
  ASSERT_EQ(companion.start(), "");
  std::atomic<int> runs{0};
  int on_caller = 0;
  for (int round = 0; round < 2000; ++round) {
    std::thread::id ran_on;
    int result = 0;
    auto task = [&] {
      ran_on = std::this_thread::get_id();
      runs.fetch_add(1);
      result = round + 1;
    };
    companion.launch(task);
    companion.wait();
    ASSERT_EQ(result, round + 1) << "round " << round;
    ASSERT_EQ(runs.load(), round + 1) << "round " << round;
    on_caller += ran_on == std::this_thread::get_id() ? 1 : 0;
  }
  std::printf("tasks run on the caller: %d of 2000\n", on_caller);
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
