#pragma once

// The pose-graph back-end (docs/methods.md §10–§11): a node per key-frame
// pose, an edge per registration (sequential, loop closure, wheel odometry), minimised with
// Levenberg–Marquardt in Ceres (the thesis used g2o).
//
// Error of an edge (from = a, to = b, measurement Z = T_a_b):
//   E = Z⁻¹ · T_w_a⁻¹ · T_w_b,   ξ = log(E) = (rotation vector of R_E, translation t_E) ∈ R⁶
// That is the SO(3)×R³ log, not the SE(3) one: the translation part is E's translation itself,
// not V(ω)⁻¹·t_E. The two agree to first order at E = I, so information matrices, adjoints and
// the covariance composition below are the same for both; SO(3)×R³ keeps the residual cheap to
// differentiate and its translation in metres. Residual r = √Ω · ξ with Ω = Edge::information
// (6×6 over (ω [rad], t [m])), cost ½·Σ‖r‖² (Ceres' convention). The thesis' weight per edge (the
// number of matches) enters through Ω: see information_from_matches().
//
// Memory. configure() allocates every buffer the graph needs for Capacity::max_nodes and
// max_edges; after it, add_node, add_edge, remove_node, set_fixed, set_pose, copy_from and the
// queries allocate nothing (the tracking thread calls them). optimize() builds a Ceres problem on
// every call and Ceres allocates inside the solve; that is meant for the solver thread
// (BackgroundOptimizer) and is bounded by the capacity: at most 2·max_nodes parameter blocks
// (quaternion and translation per node), at most max_edges residual blocks of 6 rows with 14
// parameters each, and a sparse normal matrix of at most (6·max_nodes)² entries before
// SuiteSparse's fill-reducing ordering, whose factor is no larger than that.

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rankslam::graph {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// Sizes of the graph, fixed at configure(). The defaults hold a few minutes of key-frames at the
/// thesis' 15° / 25 cm key-frame thresholds with several loop closures per key-frame.
struct Capacity {
  /// Node slots; node ids are 0..max_nodes-1. Range [2, 65536].
  int max_nodes = 256;
  /// Edges of all kinds together. Range [1, 1048576].
  int max_edges = 2048;
};

/// What made an edge. The solver treats all kinds alike; the kind is kept for the SLAM loop and
/// reports (and decides the kind of edges composed by remove_node()).
/// kSequential: a registration chain's edge between consecutive key-frames; kPlanar: a planar
/// base's height, roll and pitch between them.
enum class EdgeKind : std::uint8_t { kSequential, kLoopClosure, kWheels, kPlanar };

/// A relative-pose measurement between two nodes.
struct Edge {
  int from = -1;
  int to = -1;
  /// Measured pose of node `to` in the frame of node `from`.
  Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
  /// Information (inverse covariance) over ξ = (rotation vector [rad], translation [m]) of the
  /// error log(T_from_to⁻¹ · T_w_from⁻¹ · T_w_to); symmetric positive definite.
  Matrix6d information = Matrix6d::Identity();
  EdgeKind kind = EdgeKind::kSequential;
};

/// Outcome of one optimisation.
struct OptimizeSummary {
  /// True when the poses were updated with a usable solution (converged or iteration limit).
  bool ok = false;
  /// Levenberg–Marquardt iterations taken (successful and rejected steps).
  int iterations = 0;
  /// ½·Σ‖r‖² before and after (Ceres' cost).
  double initial_cost = 0.0;
  double final_cost = 0.0;
  /// Wall time of the whole optimize() call, problem building included.
  double solve_ms = 0.0;
  /// Static text (valid for the program's lifetime) saying how the solve ended.
  std::string_view message;
};

/// Information matrix of a registration from its number of inlier matches: the thesis weights
/// each edge's squared error by the number of matches. With n independent matches the pose's
/// covariance shrinks as 1/n, so Ω = n · diag(σ_r⁻², σ_r⁻², σ_r⁻², σ_t⁻², σ_t⁻², σ_t⁻²), where
/// σ_r [rad] and σ_t [m] are the standard deviations a registration on a single match would
/// have (the per-match noise level: the SLAM loop chooses them). Returns the zero matrix (which
/// add_edge() rejects) when inliers < 1 or a sigma is not positive and finite.
[[nodiscard]] Matrix6d information_from_matches(int inliers, double rotation_sigma_rad,
                                                double translation_sigma_m);

/// The pose graph. Node ids are stable slots 0..max_nodes-1: a removed node's slot is reused by
/// a later add_node() (lowest free slot first), so a key-frame store can index by node id;
/// generation(id) tells a reused slot from its former node.
///
/// One thread at a time: the tracking thread owns its graph and hands copies to the solver
/// thread (BackgroundOptimizer), never sharing one graph between threads.
class PoseGraph {
 public:
  PoseGraph() = default;

  /// Set-up (allocates). Empties the graph. Returns an error text naming the bad field (e.g.
  /// "graph.max_nodes must be in [2, 65536], got 1"), or an empty string on success. Also fails
  /// when Ceres was built without SuiteSparse.
  [[nodiscard]] std::string configure(const Capacity& capacity);
  [[nodiscard]] bool configured() const { return capacity_.max_nodes > 0 && !active_.empty(); }
  [[nodiscard]] const Capacity& capacity() const { return capacity_; }

  /// Adds a node at the given world pose and returns its id, or -1 when the graph is full, not
  /// configured, or the pose is not a finite rigid transform. The first node added to a graph
  /// without a fixed node becomes the fixed one (the gauge).
  [[nodiscard]] int add_node(const Eigen::Isometry3d& T_world_node);

  /// Adds an edge. False (and nothing added) when the edge store is full, an id is not a node,
  /// from == to, the measurement is not a finite rigid transform, or the information is not
  /// finite, symmetric and positive definite.
  [[nodiscard]] bool add_edge(const Edge& edge);

  /// Retires a node and frees its slot. So that the graph stays connected, the node's edges are
  /// composed into edges between its neighbours: the neighbours, in the order they were added
  /// (key-frame order), form a chain n1–n2–…–nk, and each consecutive pair gets the edge
  ///   T_a_b = T_a_id · T_id_b,   Σ_a_b = Ad(T_id_b⁻¹) · Σ_a_id · Ad(T_id_b⁻¹)ᵀ + Σ_id_b
  /// (first-order propagation with right perturbations, the two measurements independent;
  /// Σ = Ω⁻¹). A node in a sequential chain, (a,id)+(id,b), thus becomes the exact edge (a,b).
  /// With more neighbours this approximates marginalisation (which would need a dense clique
  /// with correlated noise): each measurement enters at most two composed edges, where a star
  /// through one neighbour would reuse that neighbour's measurement in all of them (measured on
  /// a 40-node circle with 16 nodes removed, the chain lands half as far from the full graph's
  /// solution as the star). Edges between id and the same neighbour are parallel and yield no
  /// composed edge. The composed edge's kind is kLoopClosure if either part was one, else
  /// kWheels if either part was one, else kSequential (kPlanar with kPlanar stays kPlanar). k incident edges give at most k-1
  /// composed ones, so the edge store never overflows. If the node was the fixed one, the
  /// neighbour behind its most informative edge (or, without edges, the lowest remaining node)
  /// becomes fixed. False when id is not a node.
  bool remove_node(int id);

  /// Makes node id the fixed one (the gauge; by default the first node added). False when id
  /// is not a node.
  bool set_fixed(int id);
  [[nodiscard]] int fixed_node() const { return fixed_id_; }
  /// Holds node id where it is in every optimisation, as the fixed node is (a loaded map's
  /// key-frames: the map the new ones are placed in). Until the node is removed; not saved with
  /// the graph. False when id is not a node.
  bool hold(int id);
  [[nodiscard]] bool held(int id) const;

  /// Overwrites a node's pose (e.g. with a background optimiser's result). False when id is not
  /// a node or the pose is not a finite rigid transform.
  bool set_pose(int id, const Eigen::Isometry3d& T_world_node);

  /// Pose of node id; the identity when id is not a node (check contains() first).
  [[nodiscard]] const Eigen::Isometry3d& pose(int id) const;
  [[nodiscard]] bool contains(int id) const;
  /// Counts add_node() calls that used slot id, so a reused slot is told from its former node;
  /// 0 for a slot never used or out of range.
  [[nodiscard]] std::uint32_t generation(int id) const;

  [[nodiscard]] int node_count() const { return node_count_; }
  [[nodiscard]] int edge_count() const { return edge_count_; }
  /// Edge number index in [0, edge_count()); indices change when edges are removed.
  [[nodiscard]] const Edge& edge(int index) const;
  /// Index of the edge from `from` to `to` of this kind (the first added where several are), or
  /// -1 where there is none.
  [[nodiscard]] int find_edge(int from, int to, EdgeKind kind) const;
  /// Replaces edge index's measurement, keeping its information (a refined estimate of the same
  /// motion). False when index is out of range or the pose is not a finite rigid transform.
  bool set_measurement(int index, const Eigen::Isometry3d& T_from_to);

  /// Saving and restoring a graph (a map file): the add_node() call number of node id (0 when id
  /// is not a node) and that of the next add_node(); they order a removed node's neighbours.
  [[nodiscard]] std::uint64_t added_order(int id) const;
  [[nodiscard]] std::uint64_t next_added_order() const { return next_added_order_; }
  /// Set-up, restoring a saved graph into an emptied one (configure()): first
  /// restore_next_added_order(), then each slot's generation and, when `node`, a node there at
  /// `T_world_node` that was the `added_order`-th added, then set_fixed() and add_edge(). False
  /// when id is out of range or already a node, the pose is not a finite rigid transform or the
  /// order is not below the next one.
  void restore_next_added_order(std::uint64_t next) { next_added_order_ = next; }
  [[nodiscard]] bool restore_slot(int id, std::uint32_t generation, bool node, std::uint64_t added_order,
                                  const Eigen::Isometry3d& T_world_node);

  /// Copies another graph into this one's preallocated buffers (no allocation): node ids,
  /// generations, edges and the fixed node are kept. False (and this graph unchanged) when this
  /// graph is not configured or either of the other's capacities exceeds this one's.
  bool copy_from(const PoseGraph& other);

  /// Levenberg–Marquardt over all nodes that have edges, in place: SPARSE_NORMAL_CHOLESKY with
  /// SuiteSparse, each orientation on Ceres' EigenQuaternionManifold, the fixed node held
  /// constant, one solver thread (the tracking thread needs the other core). SuiteSparse's own
  /// OpenMP regions are kept on the calling thread by omp_set_max_active_levels(0), a setting
  /// libgomp keeps per thread and that stays with the calling thread. Poses are written back
  /// only when the solution is usable. Allocates (see the file comment). A non-null cancel that
  /// becomes true stops the solve at the end of the current iteration, leaving the poses
  /// unchanged.
  OptimizeSummary optimize(int max_iterations = 20, const std::atomic<bool>* cancel = nullptr);

  /// Total cost ½·Σ‖√Ω·ξ‖² of the current poses, as optimize() defines it (no allocation).
  [[nodiscard]] double cost() const;

 private:
  struct StoredEdge {
    Edge edge;
    Matrix6d sqrt_information;  // upper-triangular Lᵀ with Ω = L·Lᵀ
    double log_det_information = 0.0;
  };

  // An incident edge of node id as seen from its other end.
  struct Link {
    int neighbour;
    Eigen::Isometry3d T_neighbour_id;
    Matrix6d covariance;  // of T_neighbour_id's error
    EdgeKind kind;
  };
  [[nodiscard]] Link link_of(int edge_index, int id) const;
  [[nodiscard]] int lowest_active_node() const;

  Capacity capacity_{0, 0};
  int node_count_ = 0;
  int edge_count_ = 0;
  int fixed_id_ = -1;
  std::vector<Eigen::Isometry3d> T_world_node_;  // per slot
  std::vector<std::uint8_t> active_;             // per slot: 1 = a node
  std::vector<std::uint8_t> held_;               // per slot: 1 = held where it is (hold())
  std::vector<std::uint32_t> generation_;        // per slot
  std::vector<std::uint64_t> added_order_;       // per slot: add_node() call number (key-frame order)
  std::uint64_t next_added_order_ = 0;
  std::vector<StoredEdge> edges_;                // first edge_count_ are live
  std::vector<int> incident_scratch_;            // remove_node(): incident edge indices
  std::vector<StoredEdge> composed_scratch_;     // remove_node(): edges composed so far
  std::vector<double> parameters_;               // optimize(): per slot q (x, y, z, w), t (x, y, z)
};

}  // namespace rankslam::graph
