#include "rankslam/parallel/thread_team.hpp"

#include <algorithm>
#include <chrono>
#include <system_error>

#include <sched.h>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace rankslam::parallel {

namespace {

// Eases a polling core (and a sibling hyper-thread) without giving up the time slice.
inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#elif defined(__aarch64__) || defined(__arm__)
  __asm__ __volatile__("yield");
#endif
}

// Polls `done` for up to ThreadTeam::kPollBeforeSleep: true as soon as it holds, false at the
// deadline. Reading the clock costs as much as a few dozen polls; yielding lets a thread waiting
// for this core (the companion, the robot's other work) run instead of the poll.
template <class Done>
bool poll_until(const Done& done) {
  constexpr unsigned kPollsPerCheck = 64;
  const auto deadline = std::chrono::steady_clock::now() + ThreadTeam::kPollBeforeSleep;
  for (unsigned polls = 1;; ++polls) {
    if (done()) return true;
    if (polls % kPollsPerCheck == 0) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      sched_yield();
    }
    cpu_relax();
  }
}

}  // namespace

ThreadTeam::~ThreadTeam() { stop(); }

std::string ThreadTeam::start(int threads) {
  stop();
  if (threads < 1 || threads > kMaxThreads) {
    return "threads must be in [1, " + std::to_string(kMaxThreads) + "], got " +
           std::to_string(threads);
  }
  stopping_.store(false);
  workers_.reserve(static_cast<std::size_t>(threads - 1));
  for (int thread = 1; thread < threads; ++thread) {
    try {
      workers_.emplace_back([this, thread] { worker_main(thread); });
    } catch (const std::system_error& error) {
      const std::string message = "cannot start worker thread " + std::to_string(thread) + ": " + error.what();
      stop();
      return message;
    }
  }
  return {};
}

void ThreadTeam::stop() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_.store(true);
  }
  wake_.notify_all();
  for (std::thread& worker : workers_) worker.join();
  workers_.clear();
}

void ThreadTeam::work(int thread, Trampoline trampoline, void* context) {
  for (;;) {
    const int begin = next_.fetch_add(grain_, std::memory_order_relaxed);
    if (begin >= count_) return;
    trampoline(context, begin, std::min(begin + grain_, count_), thread);
  }
}

void ThreadTeam::run(int count, int grain, Trampoline trampoline, void* context) {
  if (count <= 0) return;
  grain = std::max(1, grain);
  if (workers_.empty() || count <= grain) {
    trampoline(context, 0, count, 0);
    return;
  }
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    trampoline_ = trampoline;
    context_ = context;
    count_ = count;
    grain_ = grain;
    next_.store(0, std::memory_order_relaxed);
    open_.store(true, std::memory_order_seq_cst);
    generation_.store(generation_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }
  wake_.notify_all();
  work(0, trampoline, context);
  // Every chunk has been handed out. A worker that has not joined by now has nothing left to
  // do: the loop is closed to it, so the caller never waits for a worker still waking up (or
  // not yet scheduled, when other threads hold the cores). Only the workers inside the loop are
  // waited for, since its memory (the body and what it writes) must outlive them.
  open_.store(false, std::memory_order_seq_cst);
  if (active_workers_.load(std::memory_order_seq_cst) != 0) wait_for_workers();
}

void ThreadTeam::wait_for_workers() {
  // A worker's last chunk ends within microseconds: polling for it keeps the caller on its core,
  // where sleeping on finished_ cost a wake-up (tens of microseconds) at the end of every loop
  // a worker finished last. Past kPollBeforeSleep (a worker that lost its core) it sleeps.
  const auto none_inside = [this] { return active_workers_.load(std::memory_order_acquire) == 0; };
  if (poll_until(none_inside)) return;
  std::unique_lock<std::mutex> lock(mutex_);
  finished_.wait(lock, none_inside);
}

void ThreadTeam::leave_loop() {
  if (active_workers_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
    // Under the mutex, so that a caller between its check and its sleep cannot miss it.
    const std::lock_guard<std::mutex> lock(mutex_);
    finished_.notify_one();
  }
}

bool ThreadTeam::poll_for_loop(std::uint64_t seen) const {
  return poll_until([&] {
    return generation_.load(std::memory_order_acquire) != seen || stopping_.load(std::memory_order_acquire);
  });
}

void ThreadTeam::worker_main(int thread) {
  std::uint64_t seen = 0;
  for (;;) {
    // A frame's loops follow each other within microseconds: a worker that polls for the next
    // one is in it at once, where one woken from sleep was often queued behind the caller on the
    // caller's own core. Between frames it sleeps.
    if (!poll_for_loop(seen)) {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] {
        return stopping_.load(std::memory_order_relaxed) ||
               generation_.load(std::memory_order_relaxed) != seen;
      });
    }
    if (stopping_.load(std::memory_order_acquire)) return;
    seen = generation_.load(std::memory_order_acquire);
    active_workers_.fetch_add(1, std::memory_order_seq_cst);
    if (!open_.load(std::memory_order_seq_cst)) {  // arrived after the caller had handed out every chunk
      leave_loop();
      continue;
    }
    work(thread, trampoline_, context_);
    leave_loop();
  }
}

}  // namespace rankslam::parallel
