#include "rankslam/parallel/thread_team.hpp"

#include <algorithm>
#include <system_error>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace rankslam::parallel {

namespace {

// Eases a spinning core (and its sibling hyper-thread) without giving up the time slice.
inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#elif defined(__aarch64__) || defined(__arm__)
  __asm__ __volatile__("yield");
#endif
}

// Spins until done() or kSpin has passed; true if done() held.
template <class Done>
bool spin_until(Done&& done) {
  const auto deadline = std::chrono::steady_clock::now() + ThreadTeam::kSpin;
  for (unsigned spins = 1;; ++spins) {
    if (done()) return true;
    // Reading the clock costs as much as a few dozen polls.
    if (spins % 64 == 0 && std::chrono::steady_clock::now() > deadline) return false;
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
    // Under the mutex so that a worker deciding to sleep either sees the new generation or is
    // already waiting when wake_ is notified.
    const std::lock_guard<std::mutex> lock(mutex_);
    trampoline_ = trampoline;
    context_ = context;
    count_ = count;
    grain_ = grain;
    next_.store(0, std::memory_order_relaxed);
    running_workers_.store(static_cast<int>(workers_.size()), std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_release);
  }
  wake_.notify_all();
  work(0, trampoline, context);
  // The loop's memory (the body and what it writes) is only released once every worker has
  // left it, so wait for all of them, not just for the last chunk.
  await_workers();
}

void ThreadTeam::await_workers() {
  if (spin_until([this] { return running_workers_.load(std::memory_order_acquire) == 0; })) return;
  std::unique_lock<std::mutex> lock(mutex_);
  finished_.wait(lock, [this] { return running_workers_.load(std::memory_order_acquire) == 0; });
}

bool ThreadTeam::await_loop(std::uint64_t& seen) {
  const auto changed = [&] {
    return stopping_.load(std::memory_order_acquire) ||
           generation_.load(std::memory_order_acquire) != seen;
  };
  if (!spin_until(changed)) {
    std::unique_lock<std::mutex> lock(mutex_);
    wake_.wait(lock, changed);
  }
  if (stopping_.load(std::memory_order_acquire)) return false;
  seen = generation_.load(std::memory_order_acquire);
  return true;
}

void ThreadTeam::worker_main(int thread) {
  std::uint64_t seen = 0;
  while (await_loop(seen)) {
    work(thread, trampoline_, context_);
    if (running_workers_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      // Through the mutex, so that a caller about to sleep has either seen the count reach 0 or
      // is waiting when notified.
      { const std::lock_guard<std::mutex> lock(mutex_); }
      finished_.notify_one();
    }
  }
}

}  // namespace rankslam::parallel
