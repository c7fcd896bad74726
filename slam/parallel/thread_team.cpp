#include "rankslam/parallel/thread_team.hpp"

#include <algorithm>
#include <system_error>

namespace rankslam::parallel {

ThreadTeam::~ThreadTeam() { stop(); }

std::string ThreadTeam::start(int threads) {
  stop();
  if (threads < 1 || threads > kMaxThreads) {
    return "threads must be in [1, " + std::to_string(kMaxThreads) + "], got " +
           std::to_string(threads);
  }
  stopping_ = false;
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
    stopping_ = true;
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
    running_workers_ = static_cast<int>(workers_.size());
    ++generation_;
  }
  wake_.notify_all();
  work(0, trampoline, context);
  // The loop's memory (the body and what it writes) is only released once every worker has
  // left it, so wait for all of them, not just for the last chunk.
  std::unique_lock<std::mutex> lock(mutex_);
  finished_.wait(lock, [this] { return running_workers_ == 0; });
}

void ThreadTeam::worker_main(int thread) {
  std::uint64_t seen = 0;
  for (;;) {
    Trampoline trampoline = nullptr;
    void* context = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || generation_ != seen; });
      if (stopping_) return;
      seen = generation_;
      trampoline = trampoline_;
      context = context_;
    }
    work(thread, trampoline, context);
    bool last = false;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      last = --running_workers_ == 0;
    }
    if (last) finished_.notify_one();
  }
}

}  // namespace rankslam::parallel
