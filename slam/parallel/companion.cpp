#include "rankslam/parallel/companion.hpp"

#include <system_error>

namespace rankslam::parallel {

Companion::~Companion() { stop(); }

std::string Companion::start() {
  stop();
  stopping_ = false;
  try {
    thread_ = std::thread([this] { companion_main(); });
  } catch (const std::system_error& error) {
    return std::string("cannot start the companion thread: ") + error.what();
  }
  return {};
}

void Companion::stop() {
  if (!thread_.joinable()) return;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void Companion::launch(Trampoline trampoline, void* context) {
  if (!started()) {
    trampoline(context);
    return;
  }
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    trampoline_ = trampoline;
    context_ = context;
    pending_ = true;
  }
  changed_.notify_all();
}

void Companion::wait() {
  if (!started()) return;
  std::unique_lock<std::mutex> lock(mutex_);
  if (pending_ && !claimed_) {
    // The companion has not picked the task up yet (still waking, or its core is busy): the
    // caller, which would only wait, runs it itself.
    claimed_ = true;
    const Trampoline trampoline = trampoline_;
    void* const context = context_;
    lock.unlock();
    trampoline(context);
    lock.lock();
    pending_ = false;
    claimed_ = false;
    return;
  }
  changed_.wait(lock, [this] { return !pending_; });
}

bool Companion::idle() {
  if (!started()) return true;
  const std::lock_guard<std::mutex> lock(mutex_);
  return !pending_;
}

void Companion::companion_main() {
  for (;;) {
    Trampoline trampoline = nullptr;
    void* context = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [this] { return (pending_ && !claimed_) || stopping_; });
      if (!pending_ || claimed_) return;  // stopping with nothing left to run
      claimed_ = true;
      trampoline = trampoline_;
      context = context_;
    }
    trampoline(context);
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      pending_ = false;
      claimed_ = false;
    }
    changed_.notify_all();
  }
}

}  // namespace rankslam::parallel
