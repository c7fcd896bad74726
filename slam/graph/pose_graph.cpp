#include "rankslam/graph/pose_graph.hpp"
#include "rankslam/core/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <memory>
#include <new>
#include <tuple>

#include <ceres/ceres.h>
#include <omp.h>
#include <ceres/rotation.h>

#include "rankslam/core/lie.hpp"
#include "edge_residual.hpp"

namespace rankslam::graph {
namespace {

constexpr int kMaxNodesLimit = 65536;
constexpr int kMaxEdgesLimit = 1048576;
// Information matrices within this relative distance of symmetric are accepted (and
// symmetrised); anything further is a caller's error, not rounding.
constexpr double kSymmetryTolerance = 1e-9;

// Stops the solve when the owner asks (BackgroundOptimizer's destructor).
class CancelCallback final : public ceres::IterationCallback {
 public:
  explicit CancelCallback(const std::atomic<bool>* cancel) : cancel_(cancel) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& /*summary*/) override {
    return cancel_->load(std::memory_order_relaxed) ? ceres::SOLVER_ABORT
                                                    : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::atomic<bool>* cancel_;
};

// The composed edge keeps the most specific evidence it carries: a loop closure stays one.
EdgeKind composed_kind(EdgeKind first, EdgeKind second) {
  if (first == EdgeKind::kLoopClosure || second == EdgeKind::kLoopClosure) {
    return EdgeKind::kLoopClosure;
  }
  if (first == EdgeKind::kWheels || second == EdgeKind::kWheels) return EdgeKind::kWheels;
  if (first == EdgeKind::kPlanar && second == EdgeKind::kPlanar) return EdgeKind::kPlanar;
  return EdgeKind::kSequential;
}

}  // namespace

Matrix6d information_from_matches(int inliers, double rotation_sigma_rad,
                                  double translation_sigma_m) {
  const bool valid = inliers >= 1 && std::isfinite(rotation_sigma_rad) &&
                     std::isfinite(translation_sigma_m) && rotation_sigma_rad > 0.0 &&
                     translation_sigma_m > 0.0;
  if (!valid) return Matrix6d::Zero();
  Vector6d diagonal;
  const double rotation_weight = 1.0 / (rotation_sigma_rad * rotation_sigma_rad);
  const double translation_weight = 1.0 / (translation_sigma_m * translation_sigma_m);
  diagonal << rotation_weight, rotation_weight, rotation_weight, translation_weight,
      translation_weight, translation_weight;
  Matrix6d information = (static_cast<double>(inliers) * diagonal).asDiagonal();
  if (!information.allFinite()) return Matrix6d::Zero();
  return information;
}

std::string PoseGraph::configure(const Capacity& capacity) {
  if (capacity.max_nodes < 2 || capacity.max_nodes > kMaxNodesLimit) {
    return "graph.max_nodes must be in [2, " + std::to_string(kMaxNodesLimit) + "], got " +
           std::to_string(capacity.max_nodes);
  }
  if (capacity.max_edges < 1 || capacity.max_edges > kMaxEdgesLimit) {
    return "graph.max_edges must be in [1, " + std::to_string(kMaxEdgesLimit) + "], got " +
           std::to_string(capacity.max_edges);
  }
  if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    return "graph: this Ceres was built without SuiteSparse (SPARSE_NORMAL_CHOLESKY needs it)";
  }
  const auto nodes = static_cast<std::size_t>(capacity.max_nodes);
  const auto edges = static_cast<std::size_t>(capacity.max_edges);
  capacity_ = capacity;
  node_count_ = 0;
  edge_count_ = 0;
  fixed_id_ = -1;
  T_world_node_.assign(nodes, Eigen::Isometry3d::Identity());
  active_.assign(nodes, 0);
  held_.assign(nodes, 0);
  generation_.assign(nodes, 0);
  added_order_.assign(nodes, 0);
  next_added_order_ = 0;
  edges_.assign(edges, StoredEdge{});
  incident_scratch_.assign(edges, -1);
  composed_scratch_.assign(edges, StoredEdge{});
  parameters_.assign(nodes * 7, 0.0);
  return {};
}

int PoseGraph::add_node(const Eigen::Isometry3d& T_world_node) {
  if (!configured() || node_count_ >= capacity_.max_nodes) return -1;
  if (!lie::is_finite_rigid(T_world_node)) return -1;
  const auto free_slot = std::find(active_.begin(), active_.end(), std::uint8_t{0});
  if (free_slot == active_.end()) return -1;
  const auto id = static_cast<int>(free_slot - active_.begin());
  const auto slot = static_cast<std::size_t>(id);
  active_[slot] = 1;
  held_[slot] = 0;
  ++generation_[slot];
  added_order_[slot] = next_added_order_++;
  T_world_node_[slot] = T_world_node;
  ++node_count_;
  if (fixed_id_ < 0) fixed_id_ = id;
  return id;
}

bool PoseGraph::add_edge(const Edge& edge) {
  if (!configured() || edge_count_ >= capacity_.max_edges) return false;
  if (!contains(edge.from) || !contains(edge.to) || edge.from == edge.to) return false;
  if (!lie::is_finite_rigid(edge.T_from_to)) return false;
  if (!edge.information.allFinite()) return false;
  const double scale = edge.information.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) ||
      (edge.information - edge.information.transpose()).cwiseAbs().maxCoeff() >
          kSymmetryTolerance * scale) {
    return false;
  }
  StoredEdge stored;
  stored.edge = edge;
  stored.edge.information = 0.5 * (edge.information + edge.information.transpose());
  if (!lie::sqrt_information(stored.edge.information, stored.sqrt_information,
                             stored.log_det_information)) {
    return false;
  }
  edges_[static_cast<std::size_t>(edge_count_)] = stored;
  ++edge_count_;
  return true;
}

int PoseGraph::find_edge(int from, int to, EdgeKind kind) const {
  for (int i = 0; i < edge_count_; ++i) {
    const Edge& edge = edges_[static_cast<std::size_t>(i)].edge;
    if (edge.from == from && edge.to == to && edge.kind == kind) return i;
  }
  return -1;
}

bool PoseGraph::set_measurement(int index, const Eigen::Isometry3d& T_from_to) {
  if (index < 0 || index >= edge_count_ || !lie::is_finite_rigid(T_from_to)) return false;
  edges_[static_cast<std::size_t>(index)].edge.T_from_to = T_from_to;
  return true;
}

int PoseGraph::lowest_active_node() const {
  const auto found = std::find(active_.begin(), active_.end(), std::uint8_t{1});
  return found == active_.end() ? -1 : static_cast<int>(found - active_.begin());
}

PoseGraph::Link PoseGraph::link_of(int edge_index, int id) const {
  const Edge& edge = edges_[static_cast<std::size_t>(edge_index)].edge;
  const bool outgoing = edge.from == id;
  Link link{outgoing ? edge.to : edge.from, edge.T_from_to, lie::covariance(edge.information),
            edge.kind};
  if (outgoing) {
    std::tie(link.T_neighbour_id, link.covariance) = lie::invert(edge.T_from_to, link.covariance);
  }
  return link;
}

bool PoseGraph::remove_node(int id) {
  if (!contains(id)) return false;

  // Incident edges, and the most informative one (its neighbour inherits the gauge).
  int incident_count = 0;
  int best_edge = -1;
  for (int i = 0; i < edge_count_; ++i) {
    const StoredEdge& stored = edges_[static_cast<std::size_t>(i)];
    if (stored.edge.from != id && stored.edge.to != id) continue;
    incident_scratch_[static_cast<std::size_t>(incident_count++)] = i;
    if (best_edge < 0 || stored.log_det_information >
                             edges_[static_cast<std::size_t>(best_edge)].log_det_information) {
      best_edge = i;
    }
  }
  const auto neighbour_of = [&](int edge_index) {
    const Edge& edge = edges_[static_cast<std::size_t>(edge_index)].edge;
    return edge.from == id ? edge.to : edge.from;
  };
  const int heir = best_edge >= 0 ? neighbour_of(best_edge) : -1;

  // The neighbours in key-frame order, chained through the retired node (std::sort on ints
  // allocates nothing).
  const auto incident_begin = incident_scratch_.begin();
  const auto incident_end = incident_begin + incident_count;
  std::sort(incident_begin, incident_end, [&](int x, int y) {
    const std::uint64_t order_x = added_order_[static_cast<std::size_t>(neighbour_of(x))];
    const std::uint64_t order_y = added_order_[static_cast<std::size_t>(neighbour_of(y))];
    return order_x != order_y ? order_x < order_y : x < y;
  });
  int composed_count = 0;
  for (int k = 0; k + 1 < incident_count; ++k) {
    const Link a = link_of(incident_scratch_[static_cast<std::size_t>(k)], id);
    const Link b = link_of(incident_scratch_[static_cast<std::size_t>(k + 1)], id);
    if (a.neighbour == b.neighbour) continue;  // parallel edges: they constrained only id
    // Z_ab = Z_a_id · Z_id_b with right perturbations: δ_ab ≈ Ad(Z_id_b⁻¹)·δ_a_id + δ_id_b,
    // and Z_id_b⁻¹ = T_b_id.
    const auto [T_id_b, covariance_id_b] = lie::invert(b.T_neighbour_id, b.covariance);
    const Matrix6d adjoint_b_id = lie::adjoint(b.T_neighbour_id);
    const Matrix6d covariance =
        adjoint_b_id * a.covariance * adjoint_b_id.transpose() + covariance_id_b;
    StoredEdge composed;
    composed.edge.from = a.neighbour;
    composed.edge.to = b.neighbour;
    composed.edge.T_from_to = lie::renormalised(a.T_neighbour_id * T_id_b);
    const Matrix6d information = lie::covariance(0.5 * (covariance + covariance.transpose()));
    composed.edge.information = 0.5 * (information + information.transpose());
    composed.edge.kind = composed_kind(a.kind, b.kind);
    // A sum of positive definite covariances is positive definite; only a numerically
    // degenerate one (information beyond double range) fails here, and it is dropped rather
    // than poisoning the solve.
    if (!lie::sqrt_information(composed.edge.information, composed.sqrt_information,
                               composed.log_det_information)) {
      continue;
    }
    composed_scratch_[static_cast<std::size_t>(composed_count++)] = composed;
  }

  // Drop the incident edges in one order-preserving pass, then append the composed ones:
  // composed_count <= incident_count - 1, so the store cannot overflow.
  std::sort(incident_begin, incident_end);
  int kept = 0;
  int next_incident = 0;
  for (int i = 0; i < edge_count_; ++i) {
    if (next_incident < incident_count &&
        incident_scratch_[static_cast<std::size_t>(next_incident)] == i) {
      ++next_incident;
      continue;
    }
    if (kept != i) {
      edges_[static_cast<std::size_t>(kept)] = edges_[static_cast<std::size_t>(i)];
    }
    ++kept;
  }
  edge_count_ = kept;
  for (int k = 0; k < composed_count; ++k) {
    edges_[static_cast<std::size_t>(edge_count_++)] =
        composed_scratch_[static_cast<std::size_t>(k)];
  }

  const auto slot = static_cast<std::size_t>(id);
  active_[slot] = 0;
  held_[slot] = 0;
  T_world_node_[slot] = Eigen::Isometry3d::Identity();
  --node_count_;
  if (fixed_id_ == id) fixed_id_ = heir >= 0 ? heir : lowest_active_node();
  return true;
}

bool PoseGraph::hold(int id) {
  if (!contains(id)) return false;
  held_[static_cast<std::size_t>(id)] = 1;
  return true;
}

bool PoseGraph::held(int id) const { return contains(id) && held_[static_cast<std::size_t>(id)] != 0; }

bool PoseGraph::set_fixed(int id) {
  if (!contains(id)) return false;
  fixed_id_ = id;
  return true;
}

bool PoseGraph::set_pose(int id, const Eigen::Isometry3d& T_world_node) {
  if (!contains(id) || !lie::is_finite_rigid(T_world_node)) return false;
  T_world_node_[static_cast<std::size_t>(id)] = T_world_node;
  return true;
}

const Eigen::Isometry3d& PoseGraph::pose(int id) const {
  static const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();
  return contains(id) ? T_world_node_[static_cast<std::size_t>(id)] : kIdentity;
}

bool PoseGraph::contains(int id) const {
  return id >= 0 && id < static_cast<int>(active_.size()) &&
         active_[static_cast<std::size_t>(id)] != 0;
}

std::uint32_t PoseGraph::generation(int id) const {
  if (id < 0 || id >= static_cast<int>(generation_.size())) return 0;
  return generation_[static_cast<std::size_t>(id)];
}

std::uint64_t PoseGraph::added_order(int id) const {
  return contains(id) ? added_order_[static_cast<std::size_t>(id)] : 0;
}

bool PoseGraph::restore_slot(int id, std::uint32_t generation, bool node, std::uint64_t added_order,
                             const Eigen::Isometry3d& T_world_node) {
  if (!configured() || id < 0 || id >= capacity_.max_nodes || contains(id)) return false;
  const auto slot = static_cast<std::size_t>(id);
  if (node && (!lie::is_finite_rigid(T_world_node) || added_order >= next_added_order_)) return false;
  generation_[slot] = generation;
  if (!node) return true;
  active_[slot] = 1;
  held_[slot] = 0;
  added_order_[slot] = added_order;
  T_world_node_[slot] = T_world_node;
  ++node_count_;
  return true;
}

const Edge& PoseGraph::edge(int index) const {
  static const Edge kNoEdge{};
  if (index < 0 || index >= edge_count_) return kNoEdge;
  return edges_[static_cast<std::size_t>(index)].edge;
}

bool PoseGraph::copy_from(const PoseGraph& other) {
  if (this == &other) return true;
  if (!configured() || !other.configured() ||
      other.capacity_.max_nodes > capacity_.max_nodes ||
      other.capacity_.max_edges > capacity_.max_edges) {
    return false;
  }
  const auto other_nodes = static_cast<std::size_t>(other.capacity_.max_nodes);
  std::copy_n(other.T_world_node_.begin(), other_nodes, T_world_node_.begin());
  std::copy_n(other.active_.begin(), other_nodes, active_.begin());
  std::copy_n(other.held_.begin(), other_nodes, held_.begin());
  std::copy_n(other.generation_.begin(), other_nodes, generation_.begin());
  std::copy_n(other.added_order_.begin(), other_nodes, added_order_.begin());
  next_added_order_ = other.next_added_order_;
  std::fill(active_.begin() + static_cast<std::ptrdiff_t>(other_nodes), active_.end(),
            std::uint8_t{0});
  std::copy_n(other.edges_.begin(), other.edge_count_, edges_.begin());
  node_count_ = other.node_count_;
  edge_count_ = other.edge_count_;
  fixed_id_ = other.fixed_id_;
  return true;
}

double PoseGraph::cost() const {
  double total = 0.0;
  for (int i = 0; i < edge_count_; ++i) {
    const StoredEdge& stored = edges_[static_cast<std::size_t>(i)];
    const Eigen::Isometry3d error = stored.edge.T_from_to.inverse() *
                                    pose(stored.edge.from).inverse() * pose(stored.edge.to);
    total += 0.5 * (stored.sqrt_information * lie::log_so3_r3(error)).squaredNorm();
  }
  return total;
}

OptimizeSummary PoseGraph::optimize(int max_iterations, const std::atomic<bool>* cancel) {
  const auto start = SteadyClock::now();
  OptimizeSummary result;
  const auto finish = [&](std::string_view message) {
    result.message = message;
    result.solve_ms = elapsed_ms(start);
    return result;
  };
  if (!configured()) return finish("not configured");
  if (max_iterations < 1) return finish("max_iterations must be at least 1");
  if (edge_count_ == 0) {
    result.ok = true;
    return finish("no edges: nothing to optimise");
  }

  // CHOLMOD (SuiteSparse 5) runs loops of its supernodal factorisation as OpenMP regions with a
  // compiled-in team of 4 threads, whatever Ceres' num_threads says. On two cores shared with
  // tracking those threads only add contention: on the 256-node, 2048-edge graph of perf_graph
  // they doubled the solve's wall time (157 ms against 82 ms with OMP_THREAD_LIMIT=1). No active
  // parallel levels keeps the regions on this thread; libgomp holds the setting per thread, so
  // it reaches no other thread of the process.
  omp_set_max_active_levels(0);

  // Parameters per slot: quaternion (x, y, z, w: Eigen's storage order) and translation.
  for (std::size_t slot = 0; slot < active_.size(); ++slot) {
    if (active_[slot] == 0) continue;
    const Eigen::Isometry3d& T = T_world_node_[slot];
    double* node_parameters = &parameters_[7 * slot];
    Eigen::Map<Eigen::Quaterniond> q_world_node(node_parameters);
    Eigen::Map<Eigen::Vector3d> t_world_node(node_parameters + 4);
    q_world_node = Eigen::Quaterniond(T.linear()).normalized();
    t_world_node = T.translation();
  }

  // Ceres allocates (and could throw std::bad_alloc) while building and solving; the solver
  // thread must survive that, so it ends here as a failed solve with the poses unchanged.
  ceres::Solver::Summary summary;
  const auto solve = [&]() -> bool {
    ceres::EigenQuaternionManifold quaternion_manifold;
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    for (int i = 0; i < edge_count_; ++i) {
      const StoredEdge& stored = edges_[static_cast<std::size_t>(i)];
      double* a = &parameters_[7 * static_cast<std::size_t>(stored.edge.from)];
      double* b = &parameters_[7 * static_cast<std::size_t>(stored.edge.to)];
      auto* cost_function = new ceres::AutoDiffCostFunction<EdgeResidual, 6, 4, 3, 4, 3>(
          new EdgeResidual(stored.edge.T_from_to, stored.sqrt_information));
      problem.AddResidualBlock(cost_function, nullptr, a, a + 4, b, b + 4);
      problem.SetManifold(a, &quaternion_manifold);
      problem.SetManifold(b, &quaternion_manifold);
    }
    const auto hold_constant = [&](int id) {
      double* node = &parameters_[7 * static_cast<std::size_t>(id)];
      if (problem.HasParameterBlock(node)) {
        problem.SetParameterBlockConstant(node);
        problem.SetParameterBlockConstant(node + 4);
      }
    };
    if (fixed_id_ >= 0) hold_constant(fixed_id_);
    for (int id = 0; id < capacity_.max_nodes; ++id) {
      if (active_[static_cast<std::size_t>(id)] != 0 && held_[static_cast<std::size_t>(id)] != 0) hold_constant(id);
    }

    ceres::Solver::Options options;
    options.minimizer_type = ceres::TRUST_REGION;
    options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
    options.max_num_iterations = max_iterations;
    options.num_threads = 1;
    options.logging_type = ceres::SILENT;
    options.minimizer_progress_to_stdout = false;
    CancelCallback cancel_callback(cancel);
    if (cancel != nullptr) options.callbacks.push_back(&cancel_callback);
    std::string options_error;
    if (!options.IsValid(&options_error)) return false;

    ceres::Solve(options, &problem, &summary);
    return true;
  };
  try {
    if (!solve()) return finish("invalid Ceres solver options");
  } catch (const std::bad_alloc&) {
    return finish("out of memory in the solver: poses unchanged");
  } catch (const std::exception&) {
    return finish("the solver threw: poses unchanged");
  }
  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;

  if (!summary.IsSolutionUsable()) {
    switch (summary.termination_type) {
      case ceres::USER_SUCCESS:
      case ceres::USER_FAILURE:
        return finish("cancelled: poses unchanged");
      default:
        return finish("solver failed: poses unchanged");
    }
  }
  for (std::size_t slot = 0; slot < active_.size(); ++slot) {
    if (active_[slot] == 0) continue;
    const double* q = &parameters_[7 * slot];
    if (!Eigen::Map<const Eigen::Matrix<double, 7, 1>>(q).allFinite()) {
      return finish("solver returned non-finite poses: poses unchanged");
    }
  }
  for (std::size_t slot = 0; slot < active_.size(); ++slot) {
    if (active_[slot] == 0) continue;
    const double* q = &parameters_[7 * slot];
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Map<const Eigen::Quaterniond>(q).normalized().toRotationMatrix();
    T.translation() = Eigen::Map<const Eigen::Vector3d>(q + 4);
    T_world_node_[slot] = T;
  }
  result.ok = true;
  return finish(summary.termination_type == ceres::CONVERGENCE ? "converged"
                                                              : "iteration limit reached");
}

}  // namespace rankslam::graph
