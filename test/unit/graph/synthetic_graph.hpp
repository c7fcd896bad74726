#pragma once

// Synthetic pose graphs with known ground truth: key-frames on a circle in a tilted plane
// (yaw along the circle, a little roll, pitch and height change), odometry edges between
// consecutive key-frames measured with a constant yaw bias plus Gaussian noise (the kind of
// drift a frame-to-frame tracker accumulates), and loop-closure edges between chosen pairs.
// Initial node poses are the dead-reckoned chain of the measured odometry.

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "rankslam/graph/pose_graph.hpp"

namespace rankslam::graph::testing {

struct TrajectoryConfig {
  int nodes = 40;
  double radius_m = 3.0;
  double odometry_yaw_bias_rad = 0.01;      ///< added to every odometry edge's yaw
  double odometry_rotation_sigma_rad = 0.003;
  double odometry_translation_sigma_m = 0.01;
  double loop_rotation_sigma_rad = 0.002;   ///< noise of the loop-closure measurements
  double loop_translation_sigma_m = 0.005;
  std::vector<std::pair<int, int>> loops = {{39, 0}};  ///< (from, to) index pairs
  std::uint64_t seed = 1;
};

struct Trajectory {
  std::vector<Eigen::Isometry3d> T_world_true;   ///< ground truth per node index
  std::vector<Eigen::Isometry3d> T_world_initial;  ///< dead-reckoned from the odometry
  std::vector<Edge> edges;                        ///< odometry edges first, then loops
};

/// Right perturbation T·(Exp(ω), v) in the SO(3)×R³ sense the graph uses.
Eigen::Isometry3d perturbed(const Eigen::Isometry3d& T, const Vector6d& xi);

/// ξ = (rotation vector of R, t) of T: the graph's SO(3)×R³ log.
Vector6d log_so3_r3(const Eigen::Isometry3d& T);

Trajectory make_circle(const TrajectoryConfig& config);

/// Configures graph for the trajectory, adds its nodes (ids 0..n-1, at the initial poses or the
/// true ones) and edges; false when anything is rejected.
bool build_graph(const Trajectory& trajectory, bool start_at_truth, PoseGraph& graph,
                 const Capacity& capacity = Capacity{});

/// RMS position error [m] of graph's nodes against the ground truth (node id = index; nodes
/// the graph no longer contains are skipped).
double rms_position_error_m(const PoseGraph& graph, const Trajectory& trajectory);
/// Largest rotation error [rad] over the contained nodes.
double max_rotation_error_rad(const PoseGraph& graph, const Trajectory& trajectory);

}  // namespace rankslam::graph::testing
