#pragma once

// Pose-graph optimisation off the tracking thread. The tracking thread submit()s its graph: the
// graph is copied into a snapshot preallocated at configure() and a worker thread optimises the
// snapshot while tracking goes on; take_result() later hands back the optimised poses by node id.
//
// Tracking-thread calls (submit, take_result, busy, pause, resume) allocate nothing after
// configure() and never wait for a solve: they take a mutex that the worker holds only to hand
// over a job or publish a result (copying the node poses), never during the solve. The worker's
// solve allocates inside Ceres, bounded by the capacity (see pose_graph.hpp).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>

#include "rankslam/graph/pose_graph.hpp"

namespace rankslam::graph {

/// Optimised node poses by node id, as a caller-owned buffer sized at set-up.
class OptimizedPoses {
 public:
  /// Set-up (allocates) for graphs of this capacity; error text naming the field, or empty.
  [[nodiscard]] std::string configure(const Capacity& capacity);
  [[nodiscard]] int max_nodes() const { return static_cast<int>(present_.size()); }

  /// Whether node id existed in the submitted graph.
  [[nodiscard]] bool contains(int id) const;
  /// Optimised pose of node id; the identity when !contains(id).
  [[nodiscard]] const Eigen::Isometry3d& pose(int id) const;
  /// The node's PoseGraph::generation() at submission: a slot whose generation has changed since
  /// holds a different node, and this result does not apply to it.
  [[nodiscard]] std::uint32_t generation(int id) const;
  /// How the solve ended; when !summary().ok the poses are the submitted ones, unchanged.
  [[nodiscard]] const OptimizeSummary& summary() const { return summary_; }
  /// 1 for the first submit() of a BackgroundOptimizer, 2 for the next accepted one, ...
  [[nodiscard]] std::uint64_t submission() const { return submission_; }

  /// Copies the nodes of graph with this summary (no allocation). False when the graph has
  /// more node slots than this buffer.
  bool assign(const PoseGraph& graph, const OptimizeSummary& summary, std::uint64_t submission);

 private:
  std::vector<Eigen::Isometry3d> T_world_node_;
  std::vector<std::uint32_t> generation_;
  std::vector<std::uint8_t> present_;
  OptimizeSummary summary_{};
  std::uint64_t submission_ = 0;
};

/// Writes the optimised poses into graph for the nodes present in both with the same
/// generation (nodes added since submission, or in reused slots, are left to the caller, who
/// typically moves them with the correction of their neighbour). Returns how many were written;
/// 0 when !result.summary().ok. No allocation.
int apply_optimized_poses(const OptimizedPoses& result, PoseGraph& graph);

class BackgroundOptimizer {
 public:
  BackgroundOptimizer() = default;
  /// Asks a running solve to stop at the end of its current iteration and joins the worker.
  ~BackgroundOptimizer();
  BackgroundOptimizer(const BackgroundOptimizer&) = delete;
  BackgroundOptimizer& operator=(const BackgroundOptimizer&) = delete;

  /// Set-up (allocates the snapshot and the result buffer, starts the worker thread) for graphs
  /// of up to this capacity. Error text naming the field, or empty on success. Once only.
  [[nodiscard]] std::string configure(const Capacity& capacity);

  /// Copies graph into the snapshot and queues its optimisation with at most max_iterations
  /// Levenberg–Marquardt iterations. Returns false at once, queuing nothing, when a solve is
  /// pending or running, when not configured, or when graph is larger than the capacity. A
  /// result not yet taken stays available until the new one replaces it.
  [[nodiscard]] bool submit(const PoseGraph& graph, int max_iterations = 20);

  /// Copies the latest result into out and marks it taken. False when no new result is ready
  /// (or out has fewer node slots than the capacity).
  [[nodiscard]] bool take_result(OptimizedPoses& out);

  /// A submitted graph is queued or being optimised.
  [[nodiscard]] bool busy() const;

  /// While paused, a submitted graph waits and the worker stays idle (a solve already running
  /// finishes): lets the SLAM loop keep both cores through a burst of work. resume() starts the
  /// waiting solve.
  void pause();
  void resume();

  /// Blocks until no solve is queued or running, or the timeout passes; true when idle. For
  /// offline replay (deterministic results) and shutdown, not for the tracking thread. While
  /// paused with a queued graph it can only time out.
  bool wait_until_idle(std::chrono::milliseconds timeout);

  /// Solves finished since configure().
  [[nodiscard]] std::uint64_t completed() const;

 private:
  void run();

  mutable std::mutex mutex_;
  std::condition_variable wake_worker_;
  std::condition_variable idle_;
  std::thread worker_;
  std::atomic<bool> stop_{false};  // read by the solve's iteration callback without the mutex
  bool configured_ = false;
  bool job_pending_ = false;
  bool running_ = false;
  bool paused_ = false;
  bool result_ready_ = false;
  int max_iterations_ = 20;
  std::uint64_t submitted_ = 0;
  std::uint64_t completed_ = 0;
  PoseGraph snapshot_;      // written by submit() only while no job is pending or running
  OptimizedPoses result_;   // guarded by mutex_
};

}  // namespace rankslam::graph
