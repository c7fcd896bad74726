#pragma once

// A fixed team of threads that shares the per-frame loops of the front-end (normals, saliency,
// descriptors, matching, hypotheses) between the cores of the robot computer. The threads are
// started at set-up, poll briefly for the next loop and then sleep until one comes; a loop
// allocates nothing and returns when every index is done, so callers see a plain blocking call.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

namespace rankslam::parallel {

class ThreadTeam {
 public:
  /// Largest team: the per-thread scratch of the callers is sized by size(), and more threads
  /// than this buy nothing on the loops it serves (a few thousand items each).
  static constexpr int kMaxThreads = 8;
  /// How long an idle worker polls for the next loop before it sleeps: longer than the gaps
  /// between a frame's loops, far shorter than the gap between frames.
  static constexpr std::chrono::microseconds kPollBeforeSleep{200};

  /// A team of one: every loop runs on the calling thread.
  ThreadTeam() = default;
  ~ThreadTeam();
  ThreadTeam(const ThreadTeam&) = delete;
  ThreadTeam& operator=(const ThreadTeam&) = delete;

  /// Set-up (allocates, starts threads): the calling thread plus threads − 1 workers. A team that
  /// was started before is stopped first. Empty on success, else why it failed.
  [[nodiscard]] std::string start(int threads);

  /// Threads taking part in a loop, the caller included (1 before start()).
  [[nodiscard]] int size() const { return static_cast<int>(workers_.size()) + 1; }

  /// Calls body(begin, end, thread) on consecutive chunks of at most `grain` indices that cover
  /// [0, count) once each, on every thread of the team; `thread` (0 = the caller) is below
  /// size(), for per-thread scratch. A team of one, or a loop of one chunk, makes one call over
  /// the whole range. Chunks go to whichever thread asks first, so the body must
  /// write only what belongs to its indices. Blocks until all chunks are done. The body must not
  /// throw, and must not call for_chunks of the same team (not re-entrant).
  template <class Body>
  void for_chunks(int count, int grain, Body&& body) {
    using Decayed = std::remove_reference_t<Body>;
    run(count, grain,
        [](void* context, int begin, int end, int thread) {
          (*static_cast<Decayed*>(context))(begin, end, thread);
        },
        const_cast<void*>(static_cast<const void*>(&body)));
  }

  /// Calls body(part, thread) once for each part in [0, parts), parts spread over the team.
  template <class Body>
  void for_each(int parts, Body&& body) {
    for_chunks(parts, 1, [&body](int begin, int end, int thread) {
      for (int part = begin; part < end; ++part) body(part, thread);
    });
  }

 private:
  using Trampoline = void (*)(void* context, int begin, int end, int thread);

  void run(int count, int grain, Trampoline trampoline, void* context);
  void work(int thread, Trampoline trampoline, void* context);
  void worker_main(int thread);
  /// Polls for a loop after `seen` (or stop) for up to kPollBeforeSleep; true if one came.
  [[nodiscard]] bool poll_for_loop(std::uint64_t seen) const;
  /// The caller's wait for the workers inside the closed loop: polls, then sleeps.
  void wait_for_workers();
  /// A worker leaves the loop it joined; the last one out wakes a sleeping caller.
  void leave_loop();
  void stop();

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable finished_;
  // The loop being run, written by the caller before it opens the loop; a worker reads it only
  // once it has joined (counted itself in active_workers_ and seen the loop open), and the
  // caller writes the next one only once every worker has left.
  Trampoline trampoline_ = nullptr;
  void* context_ = nullptr;
  int count_ = 0;
  int grain_ = 1;
  std::atomic<std::uint64_t> generation_{0};  // written under mutex_, polled without it
  // Workers may still join the current loop. A worker counts itself in, then checks this; the
  // caller clears it, then waits for the count: one of the two always sees the other.
  std::atomic<bool> open_{false};
  std::atomic<int> active_workers_{0};  // workers inside the current loop
  std::atomic<bool> stopping_{false};
  std::atomic<int> next_{0};
};

/// team->for_chunks(count, grain, body), or one call body(0, count, 0) without a team: for
/// components whose team is optional.
template <class Body>
void for_chunks(ThreadTeam* team, int count, int grain, Body&& body) {
  if (team != nullptr) {
    team->for_chunks(count, grain, body);
  } else if (count > 0) {
    body(0, count, 0);
  }
}

/// team->for_each(parts, body), or every part in order on the caller without a team.
template <class Body>
void for_each(ThreadTeam* team, int parts, Body&& body) {
  if (team != nullptr) {
    team->for_each(parts, body);
  } else {
    for (int part = 0; part < parts; ++part) body(part, 0);
  }
}

/// Threads of an optional team (1 without one).
[[nodiscard]] inline int team_size(const ThreadTeam* team) { return team != nullptr ? team->size() : 1; }

}  // namespace rankslam::parallel
