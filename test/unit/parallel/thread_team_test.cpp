#include "rankslam/parallel/thread_team.hpp"

#include <atomic>
#include <chrono>
#include <thread>
#include <cstdint>
#include <numeric>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"

namespace rankslam::parallel {
namespace {

TEST(ThreadTeam, RefusesATeamSizeOutOfRange) {
  ThreadTeam team;
  EXPECT_NE(team.start(0), "");
  EXPECT_NE(team.start(ThreadTeam::kMaxThreads + 1), "");
  EXPECT_EQ(team.size(), 1);
  EXPECT_EQ(team.start(2), "");
  EXPECT_EQ(team.size(), 2);
}

TEST(ThreadTeam, AnUnstartedTeamRunsTheWholeLoopOnTheCaller) {
  ThreadTeam team;
  std::vector<int> visits(100, 0);
  team.for_chunks(100, 7, [&](int begin, int end, int thread) {
    EXPECT_EQ(thread, 0);
    for (int i = begin; i < end; ++i) ++visits[static_cast<std::size_t>(i)];
  });
  for (const int v : visits) EXPECT_EQ(v, 1);
}

// Every index once, every thread number in range, over 600 loops of varied sizes and grains:
// a lost wake-up or a chunk handed out twice shows here. (Whether the workers take any of these
// short loops' chunks depends on when they get a core; AWorkerTakesTheChunksTheCallerCannot
// checks that they take part.)
TEST(ThreadTeam, EveryIndexIsVisitedOnceInEveryLoop) {
  for (const int threads : {2, 3, 4}) {
    ThreadTeam team;
    ASSERT_EQ(team.start(threads), "");
    std::vector<std::atomic<int>> visits(5000);
    for (int loop = 0; loop < 600; ++loop) {
      const int count = 1 + (loop * 37) % 5000;
      const int grain = 1 + loop % 64;
      for (int i = 0; i < count; ++i) visits[static_cast<std::size_t>(i)].store(0);
      team.for_chunks(count, grain, [&](int begin, int end, int thread) {
        ASSERT_GE(thread, 0);
        ASSERT_LT(thread, threads);
        ASSERT_LE(end - begin, grain);
        for (int i = begin; i < end; ++i) visits[static_cast<std::size_t>(i)].fetch_add(1);
      });
      int wrong = 0;
      for (int i = 0; i < count; ++i) wrong += visits[static_cast<std::size_t>(i)].load() != 1 ? 1 : 0;
      ASSERT_EQ(wrong, 0) << "loop " << loop << " of " << count << " indices, grain " << grain;
    }
  }
}

// A worker takes part: the caller's chunk waits (bounded) until another thread has taken the
// other chunk, which only a worker can do while the caller is inside its own.
TEST(ThreadTeam, AWorkerTakesTheChunksTheCallerCannot) {
  ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  for (int loop = 0; loop < 50; ++loop) {
    std::atomic<int> taken_by_worker{0};
    std::atomic<bool> timed_out{false};
    team.for_chunks(2, 1, [&](int begin, int, int thread) {
      if (thread != 0) {
        taken_by_worker.fetch_add(1);
        return;
      }
      if (begin != 0) return;  // a worker already holds chunk 0
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
      while (taken_by_worker.load() == 0) {
        if (std::chrono::steady_clock::now() > deadline) {
          timed_out = true;
          return;
        }
        std::this_thread::yield();
      }
    });
    ASSERT_FALSE(timed_out.load()) << "loop " << loop << ": no worker took the second chunk in 20 s";
    // Whichever chunk the caller took (if any), the other went to the worker.
    ASSERT_GE(taken_by_worker.load(), 1) << "loop " << loop;
  }
}

// The caller returns only once the workers inside the loop are done, and sees what they wrote:
// whether a worker's chunk ends while the caller polls for it (microseconds) or after the
// caller has gone to sleep (milliseconds).
TEST(ThreadTeam, TheCallerWaitsForAWorkerThatFinishesLast) {
  ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  for (const auto work : {std::chrono::microseconds(20), std::chrono::microseconds(3000)}) {
    int finished_by_worker = 0;
    for (int loop = 0; loop < 20; ++loop) {
      int written = -1;  // plain: the loop's end must order the worker's write before the read
      std::atomic<bool> worker_took_part{false};
      team.for_chunks(2, 1, [&](int, int, int thread) {
        if (thread == 0) {
          // The caller's chunk lasts until a worker holds the other one (or a bounded while).
          const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
          while (!worker_took_part.load() && std::chrono::steady_clock::now() < deadline) {
          }
          return;
        }
        worker_took_part = true;
        const auto until = std::chrono::steady_clock::now() + work;
        while (std::chrono::steady_clock::now() < until) {
        }
        written = loop;
      });
      if (!worker_took_part.load()) continue;
      ASSERT_EQ(written, loop) << "the caller returned before the worker's chunk ended";
      ++finished_by_worker;
    }
    EXPECT_GT(finished_by_worker, 0) << "no worker took part in " << work.count() << " µs loops";
  }
}

TEST(ThreadTeam, ForEachGivesEveryPartOnce) {
  ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  std::vector<int> parts(64, 0);
  team.for_each(64, [&](int part, int /*thread*/) { parts[static_cast<std::size_t>(part)] += part; });
  for (int p = 0; p < 64; ++p) EXPECT_EQ(parts[static_cast<std::size_t>(p)], p);
}

// The loops run per frame: after start() they allocate nothing on any thread.
TEST(ThreadTeam, LoopsAllocateNothingAfterStart) {
  ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  std::vector<std::int64_t> sums(2, 0);
  team.for_chunks(1000, 10, [&](int, int, int) {});  // first wake-up outside the count
  test_support::CountAllocations count;
  for (int loop = 0; loop < 500; ++loop) {
    team.for_chunks(1000, 10, [&](int begin, int end, int thread) {
      for (int i = begin; i < end; ++i) sums[static_cast<std::size_t>(thread)] += i;
    });
  }
  EXPECT_EQ(count.allocations(), 0);
  EXPECT_EQ(sums[0] + sums[1], 500LL * 999 * 1000 / 2);
}

TEST(ThreadTeam, RestartingChangesTheTeamSize) {
  ThreadTeam team;
  ASSERT_EQ(team.start(3), "");
  EXPECT_EQ(team.size(), 3);
  ASSERT_EQ(team.start(1), "");
  EXPECT_EQ(team.size(), 1);
  int total = 0;
  team.for_chunks(10, 3, [&](int begin, int end, int) { total += end - begin; });
  EXPECT_EQ(total, 10);
}

}  // namespace
}  // namespace rankslam::parallel
