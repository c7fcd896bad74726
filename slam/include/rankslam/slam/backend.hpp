#pragma once

#include "rankslam/graph/background_optimizer.hpp"
#include "rankslam/graph/pose_graph.hpp"
#include "rankslam/nav/wheel_arbiter.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/keyframe_store.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>

namespace rankslam::slam {

/// The pose-graph back-end (docs/methods.md §11): a node per stored key-frame, edges for the
/// registrations between consecutive key-frames (with the planar-base and wheel edges where the
/// robot has them) and for loop closures, optimised on a background thread; a finished solve
/// moves the stored key-frames. Everything is sized at construction.
class Backend {
 public:
  /// Throws std::invalid_argument when the graph cannot be sized.
  Backend(const SlamConfig& config, const Eigen::Isometry3d& T_base_cam, bool differential_drive);

  /// Offline replay: wait for each solve on the caller's schedule (results independent of thread
  /// timing). Live runs leave it off.
  void set_synchronous(bool synchronous) { synchronous_ = synchronous; }

  /// A key-frame's node at `T_world_cam`, or -1 when the graph is full; its generation.
  [[nodiscard]] int add_node(const Eigen::Isometry3d& T_world_cam, std::uint32_t& generation);
  /// A retired key-frame's node: its edges are composed through a neighbour.
  void remove_node(int node) { graph_.remove_node(node); }
  /// Between consecutive key-frames: the registration chain's edge with `information`, then the
  /// planar-base edge and the wheel edge where they apply.
  void add_sequential_edges(int from_node, int to_node, const Eigen::Isometry3d& T_from_to,
                            const Eigen::Matrix<double, 6, 6>& information);
  /// A better estimate of the registration edge between two key-frames' nodes (local mapping):
  /// replaces its measurement and optimises the graph at the next chance. False where the nodes
  /// are no longer those generations, have no such edge or are both held (a loaded map's).
  bool refine_sequential_edge(int from_node, std::uint32_t from_generation, int to_node,
                              std::uint32_t to_generation, const Eigen::Isometry3d& T_from_to);
  /// Starts the wheel motion since the latest key-frame afresh (at a new key-frame).
  void restart_wheel_motion();
  /// The wheels did not see the motion since the latest key-frame (a relocalisation chose another
  /// one): the next key-frame has no wheel edge.
  void forget_wheel_motion() { wheel_since_keyframe_valid_ = false; }
  /// The wheel motion of one frame since the previous (null: none; the wheel edge is then lost
  /// until the next key-frame).
  void accumulate_wheel_motion(const nav::MotionPrior* prior);
  /// A loop closure; false when the graph is full. The graph is optimised at the next chance.
  [[nodiscard]] bool add_loop_closure(const graph::Edge& edge);

  /// Submits a changed graph when the optimiser is free (waiting for it when synchronous).
  void submit_pending();
  /// Takes a finished solve, if any, into the store's key-frames: true with the world-frame
  /// correction of the newest key-frame the solve included, which every tracked pose takes.
  [[nodiscard]] bool take_solve(KeyframeStore& store, Eigen::Isometry3d& correction);
  /// End of a run: the pending graph solved and taken (see take_solve), each correction handed
  /// to `apply`.
  template <class Apply>
  void finish(KeyframeStore& store, Apply&& apply) {
    Eigen::Isometry3d correction;
    if (pending_) {
      (void)optimizer_.wait_until_idle(kFinishWait);
      if (take_solve(store, correction)) apply(correction);
      if (optimizer_.submit(graph_, config_.graph.iterations)) pending_ = false;
    }
    (void)optimizer_.wait_until_idle(kFinishWait);
    if (take_solve(store, correction)) apply(correction);
  }

  /// The pose of a frame re-expressed on its key-frame's optimised pose; false when the
  /// key-frame was retired.
  [[nodiscard]] bool optimized_pose(int keyframe_node, std::uint32_t keyframe_generation,
                                    const Eigen::Isometry3d& T_keyframe_cam, Eigen::Isometry3d& T_world_cam) const;

  /// The graph, saved with the map; set-up alone restores it (a map file), with nothing pending.
  [[nodiscard]] const graph::PoseGraph& graph() const { return graph_; }
  [[nodiscard]] graph::PoseGraph& graph_to_restore() {
    pending_ = false;
    return graph_;
  }

  /// Pose-graph information of a registration from its inlier count and noise scale.
  [[nodiscard]] Eigen::Matrix<double, 6, 6> registration_information(int inliers, double noise_scale) const;
  /// Information added to every sequential registration so that a direction the surfaces leave
  /// free keeps the graph non-singular.
  [[nodiscard]] Eigen::Matrix<double, 6, 6> sequential_information_floor() const;

 private:
  static constexpr auto kFinishWait = std::chrono::minutes(5);

  /// On a differential-drive base: an edge holding the base's height, roll and pitch between
  /// two key-frames (graph_planar_sigma_*).
  void add_planar_edge(int from_node, int to_node, const Eigen::Isometry3d& T_from_to);
  /// The wheel motion since the last key-frame, composed frame by frame with its covariance.
  void add_wheel_edge(int from_node, int to_node);

  const SlamConfig& config_;
  Eigen::Isometry3d T_base_cam_;
  bool differential_drive_;
  graph::PoseGraph graph_;
  graph::BackgroundOptimizer optimizer_;
  graph::OptimizedPoses optimized_;
  bool pending_ = false;
  bool synchronous_ = false;
  Eigen::Isometry3d wheel_since_keyframe_ = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> wheel_since_keyframe_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  bool wheel_since_keyframe_valid_ = false;
};

}  // namespace rankslam::slam
