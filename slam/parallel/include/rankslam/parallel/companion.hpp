#pragma once

// One thread beside the caller that runs one task at a time: the caller hands it a task, goes on
// with work of its own, and waits for the task before it uses the task's results. The SLAM loop
// extracts a frame's photometric features on it while the geometric front-end runs on the
// caller's thread team. The thread is started at set-up; handing a task over allocates nothing.

#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>

namespace rankslam::parallel {

class Companion {
 public:
  /// Not started: every task runs on the caller, inside launch().
  Companion() = default;
  ~Companion();
  Companion(const Companion&) = delete;
  Companion& operator=(const Companion&) = delete;

  /// Set-up (starts the thread). Empty on success, else why it failed.
  [[nodiscard]] std::string start();
  [[nodiscard]] bool started() const { return thread_.joinable(); }

  /// Runs task() on the companion thread (on the caller when not started, or when the companion
  /// has not picked it up by the time the caller waits). `task` must stay alive, and what it
  /// touches untouched by the caller, until wait() returns; one task at a time. The task must
  /// not throw, and must be fit to run on either thread.
  template <class Task>
  void launch(Task& task) {
    using Decayed = std::remove_const_t<Task>;
    launch([](void* context) { (*static_cast<Decayed*>(context))(); },
           const_cast<void*>(static_cast<const void*>(&task)));
  }

  /// Returns once the launched task has finished (at once when none is running). A task the
  /// companion has not started yet runs on the caller, inside wait().
  void wait();
  /// Whether the launched task has finished (true when none was launched); never waits for it.
  [[nodiscard]] bool idle();

 private:
  using Trampoline = void (*)(void* context);
  void launch(Trampoline trampoline, void* context);
  void companion_main();
  void stop();

  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable changed_;
  Trampoline trampoline_ = nullptr;
  void* context_ = nullptr;
  bool pending_ = false;  // a task handed over and not finished yet
  bool claimed_ = false;  // the pending task is running, on the companion or on the caller
  bool stopping_ = false;
};

}  // namespace rankslam::parallel
