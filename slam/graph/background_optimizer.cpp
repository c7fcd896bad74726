#include "rankslam/graph/background_optimizer.hpp"

#include <algorithm>
#include <system_error>

namespace rankslam::graph {

std::string OptimizedPoses::configure(const Capacity& capacity) {
  if (capacity.max_nodes < 2) {
    return "graph.max_nodes must be at least 2, got " + std::to_string(capacity.max_nodes);
  }
  const auto nodes = static_cast<std::size_t>(capacity.max_nodes);
  T_world_node_.assign(nodes, Eigen::Isometry3d::Identity());
  generation_.assign(nodes, 0);
  present_.assign(nodes, 0);
  summary_ = OptimizeSummary{};
  submission_ = 0;
  return {};
}

bool OptimizedPoses::contains(int id) const {
  return id >= 0 && id < max_nodes() && present_[static_cast<std::size_t>(id)] != 0;
}

const Eigen::Isometry3d& OptimizedPoses::pose(int id) const {
  static const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();
  return contains(id) ? T_world_node_[static_cast<std::size_t>(id)] : kIdentity;
}

std::uint32_t OptimizedPoses::generation(int id) const {
  return contains(id) ? generation_[static_cast<std::size_t>(id)] : 0;
}

bool OptimizedPoses::assign(const PoseGraph& graph, const OptimizeSummary& summary,
                            std::uint64_t submission) {
  const int slots = graph.capacity().max_nodes;
  if (slots > max_nodes()) return false;
  std::fill(present_.begin(), present_.end(), std::uint8_t{0});
  for (int id = 0; id < slots; ++id) {
    if (!graph.contains(id)) continue;
    const auto slot = static_cast<std::size_t>(id);
    present_[slot] = 1;
    T_world_node_[slot] = graph.pose(id);
    generation_[slot] = graph.generation(id);
  }
  summary_ = summary;
  submission_ = submission;
  return true;
}

int apply_optimized_poses(const OptimizedPoses& result, PoseGraph& graph) {
  if (!result.summary().ok) return 0;
  int written = 0;
  const int slots = std::min(result.max_nodes(), graph.capacity().max_nodes);
  for (int id = 0; id < slots; ++id) {
    if (!result.contains(id) || !graph.contains(id)) continue;
    if (result.generation(id) != graph.generation(id)) continue;
    if (graph.set_pose(id, result.pose(id))) ++written;
  }
  return written;
}

BackgroundOptimizer::~BackgroundOptimizer() {
  {
    const std::lock_guard lock(mutex_);
    stop_.store(true);
  }
  wake_worker_.notify_all();
  if (worker_.joinable()) worker_.join();
}

std::string BackgroundOptimizer::configure(const Capacity& capacity) {
  const std::lock_guard lock(mutex_);
  if (configured_) return "graph: background optimizer is already configured";
  if (std::string error = snapshot_.configure(capacity); !error.empty()) return error;
  if (std::string error = result_.configure(capacity); !error.empty()) return error;
  try {
    worker_ = std::thread([this] { run(); });
  } catch (const std::system_error& error) {
    return std::string("graph: cannot start the optimiser thread: ") + error.what();
  }
  configured_ = true;
  return {};
}

bool BackgroundOptimizer::submit(const PoseGraph& graph, int max_iterations) {
  {
    const std::lock_guard lock(mutex_);
    if (!configured_ || job_pending_ || running_ || max_iterations < 1) return false;
    if (!snapshot_.copy_from(graph)) return false;
    max_iterations_ = max_iterations;
    ++submitted_;
    job_pending_ = true;
  }
  wake_worker_.notify_one();
  return true;
}

bool BackgroundOptimizer::take_result(OptimizedPoses& out) {
  const std::lock_guard lock(mutex_);
  if (!result_ready_ || out.max_nodes() < result_.max_nodes()) return false;
  // Same capacity on both sides, so the vectors' copy assignment reuses out's storage.
  out = result_;
  result_ready_ = false;
  return true;
}

bool BackgroundOptimizer::busy() const {
  const std::lock_guard lock(mutex_);
  return job_pending_ || running_;
}

void BackgroundOptimizer::pause() {
  const std::lock_guard lock(mutex_);
  paused_ = true;
}

void BackgroundOptimizer::resume() {
  {
    const std::lock_guard lock(mutex_);
    paused_ = false;
  }
  wake_worker_.notify_one();
}

bool BackgroundOptimizer::wait_until_idle(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return idle_.wait_for(lock, timeout, [this] { return !job_pending_ && !running_; });
}

std::uint64_t BackgroundOptimizer::completed() const {
  const std::lock_guard lock(mutex_);
  return completed_;
}

void BackgroundOptimizer::run() {
  std::unique_lock lock(mutex_);
  while (true) {
    wake_worker_.wait(lock, [this] { return stop_.load() || (job_pending_ && !paused_); });
    if (stop_.load()) return;
    job_pending_ = false;
    running_ = true;
    const int max_iterations = max_iterations_;
    const std::uint64_t submission = submitted_;
    lock.unlock();

    // The snapshot is the worker's alone while running_: submit() refuses to touch it.
    const OptimizeSummary summary = snapshot_.optimize(max_iterations, &stop_);

    lock.lock();
    result_.assign(snapshot_, summary, submission);
    result_ready_ = true;
    running_ = false;
    ++completed_;
    idle_.notify_all();
  }
}

}  // namespace rankslam::graph
