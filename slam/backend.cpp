#include "rankslam/slam/backend.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/units.hpp"
#include "rankslam/slam/registration_support.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace rankslam::slam {

using lie::Matrix6d;

Backend::Backend(const SlamConfig& config, const Eigen::Isometry3d& T_base_cam, bool differential_drive)
    : config_(config), T_base_cam_(T_base_cam), differential_drive_(differential_drive) {
  // Room for a sequential edge per key-frame and several loop closures each.
  constexpr int kEdgesPerKeyframe = 8;
  const graph::Capacity capacity{config_.keyframe_capacity, config_.keyframe_capacity * kEdgesPerKeyframe};
  for (const std::string& error : {graph_.configure(capacity), optimizer_.configure(capacity), optimized_.configure(capacity)}) {
    if (!error.empty()) throw std::invalid_argument(error);
  }
}

int Backend::add_node(const Eigen::Isometry3d& T_world_cam, std::uint32_t& generation) {
  const int node = graph_.add_node(T_world_cam);
  generation = node >= 0 ? graph_.generation(node) : 0;
  return node;
}

void Backend::add_sequential_edges(int from_node, int to_node, const Eigen::Isometry3d& T_from_to,
                                   const Matrix6d& information) {
  graph::Edge edge;
  edge.from = from_node;
  edge.to = to_node;
  edge.T_from_to = T_from_to;
  edge.information = information;
  edge.kind = graph::EdgeKind::kSequential;
  (void)graph_.add_edge(edge);
  add_planar_edge(from_node, to_node, T_from_to);
  add_wheel_edge(from_node, to_node);
}

bool Backend::refine_sequential_edge(int from_node, std::uint32_t from_generation, int to_node,
                                     std::uint32_t to_generation, const Eigen::Isometry3d& T_from_to) {
  if (!graph_.contains(from_node) || !graph_.contains(to_node) || graph_.generation(from_node) != from_generation ||
      graph_.generation(to_node) != to_generation) {
    return false;
  }
  // A loaded map's key-frames are held where it put them: its edges stay as saved.
  if (graph_.held(from_node) && graph_.held(to_node)) return false;
  const int edge = graph_.find_edge(from_node, to_node, graph::EdgeKind::kSequential);
  if (edge < 0 || !graph_.set_measurement(edge, lie::renormalised(T_from_to))) return false;
  pending_ = true;
  return true;
}

void Backend::restart_wheel_motion() {
  wheel_since_keyframe_ = Eigen::Isometry3d::Identity();
  wheel_since_keyframe_covariance_.setZero();
  wheel_since_keyframe_valid_ = true;
}

void Backend::accumulate_wheel_motion(const nav::MotionPrior* prior) {
  if (prior == nullptr) {
    wheel_since_keyframe_valid_ = false;
    return;
  }
  // Both covariances are of a small motion applied on the left in the earlier frame:
  // exp(ξ_a)·A · exp(ξ_b)·B = exp(ξ_a + Ad(A)·ξ_b)·A·B to first order.
  const Matrix6d to_keyframe = lie::adjoint(wheel_since_keyframe_);
  wheel_since_keyframe_covariance_ += to_keyframe * prior->covariance * to_keyframe.transpose();
  wheel_since_keyframe_ = lie::renormalised(wheel_since_keyframe_ * prior->T_previous_current);
}

bool Backend::add_loop_closure(const graph::Edge& edge) {
  if (!graph_.add_edge(edge)) return false;
  pending_ = true;
  return true;
}

void Backend::submit_pending() {
  if (pending_ && !optimizer_.busy() && optimizer_.submit(graph_, config_.graph.iterations)) {
    pending_ = false;
    if (synchronous_) (void)optimizer_.wait_until_idle(kFinishWait);
  }
}

bool Backend::take_solve(KeyframeStore& store, Eigen::Isometry3d& correction) {
  if (!optimizer_.take_result(optimized_) || !optimized_.summary().ok) return false;
  // The newest key-frame the solve included carries the tracking: its correction moves the
  // key-frames added since and every pose the tracking holds.
  correction = Eigen::Isometry3d::Identity();
  std::int64_t newest = -1;
  for (int i = 0; i < store.capacity(); ++i) {
    StoredKeyframe& keyframe = store.slot(i);
    if (!keyframe.used || keyframe.node < 0 || !optimized_.contains(keyframe.node) ||
        optimized_.generation(keyframe.node) != keyframe.generation) {
      continue;
    }
    const Eigen::Isometry3d& optimized = optimized_.pose(keyframe.node);
    if (keyframe.sequence > newest) {
      newest = keyframe.sequence;
      correction = lie::renormalised(optimized * keyframe.T_world_cam.inverse());
    }
    keyframe.T_world_cam = optimized;
    (void)graph_.set_pose(keyframe.node, optimized);
  }
  if (newest < 0) return false;
  for (int i = 0; i < store.capacity(); ++i) {
    StoredKeyframe& keyframe = store.slot(i);
    if (!keyframe.used || keyframe.node < 0) continue;
    if (optimized_.contains(keyframe.node) && optimized_.generation(keyframe.node) == keyframe.generation) continue;
    keyframe.T_world_cam = lie::renormalised(correction * keyframe.T_world_cam);
    (void)graph_.set_pose(keyframe.node, keyframe.T_world_cam);
  }
  return true;
}

bool Backend::optimized_pose(int keyframe_node, std::uint32_t keyframe_generation,
                             const Eigen::Isometry3d& T_keyframe_cam, Eigen::Isometry3d& T_world_cam) const {
  if (keyframe_node < 0 || !graph_.contains(keyframe_node) || graph_.generation(keyframe_node) != keyframe_generation) {
    return false;
  }
  T_world_cam = lie::renormalised(graph_.pose(keyframe_node) * T_keyframe_cam);
  return true;
}

void Backend::add_planar_edge(int from_node, int to_node, const Eigen::Isometry3d& T_from_to) {
  if (!differential_drive_ || config_.graph.planar_sigma_m <= 0.0 || config_.graph.planar_sigma_deg <= 0.0) return;
  // A differential-drive base stays on the floor: between two key-frames its height, roll and
  // pitch do not change. The graph composes edges through covariances when it retires a node,
  // hence the floor on the free three (see planar_constraint).
  const PlanarConstraint constraint = planar_constraint(T_from_to, T_base_cam_, config_.graph.planar_sigma_m,
                                                        deg_to_rad(config_.graph.planar_sigma_deg));
  graph::Edge edge;
  edge.from = from_node;
  edge.to = to_node;
  edge.T_from_to = lie::renormalised(constraint.T_from_to);
  edge.information = constraint.information;
  edge.kind = graph::EdgeKind::kPlanar;
  (void)graph_.add_edge(edge);
}

void Backend::add_wheel_edge(int from_node, int to_node) {
  if (!wheel_since_keyframe_valid_ || config_.graph.wheel_floor_m <= 0.0) return;
  // The graph's error sits on the right, in the later key-frame: Σ_right = Ad(T⁻¹)·Σ_left·Ad(T⁻¹)ᵀ.
  // Motion a planar base cannot measure (roll, pitch, height) has no wheel variance; the floor
  // keeps the information finite there.
  const Matrix6d to_current = lie::adjoint(wheel_since_keyframe_.inverse());
  Matrix6d covariance = to_current * wheel_since_keyframe_covariance_ * to_current.transpose();
  const double floor_rad = deg_to_rad(config_.graph.wheel_floor_deg);
  covariance.diagonal().head<3>().array() += floor_rad * floor_rad;
  covariance.diagonal().tail<3>().array() += config_.graph.wheel_floor_m * config_.graph.wheel_floor_m;
  graph::Edge edge;
  edge.from = from_node;
  edge.to = to_node;
  edge.T_from_to = wheel_since_keyframe_;
  edge.information = lie::symmetric_inverse(covariance);
  edge.kind = graph::EdgeKind::kWheels;
  (void)graph_.add_edge(edge);
}

Matrix6d Backend::sequential_information_floor() const {
  // One match's rotation information and a hundredth of its translation information: what the
  // surfaces leave free must not make the graph singular.
  return graph::information_from_matches(1, deg_to_rad(config_.graph.match_sigma_deg),
                                         10.0 * config_.graph.match_sigma_m);
}

Matrix6d Backend::registration_information(int inliers, double noise_scale) const {
  // The thesis weights an edge by its inlier count, which presumes every registration fits its
  // matches as well as their predicted noise says. Where the inliers fit worse (noise scale s > 1:
  // a blurred key-frame, a rolling-shutter velocity that was off, an alignment pulled by a wrong
  // subset), the registration is that much less certain: the a-posteriori variance factor s²
  // divides the information. Below 1 the noise model is merely conservative and the count
  // stands.
  const double variance_factor = std::max(1.0, noise_scale * noise_scale);
  return graph::information_from_matches(inliers, deg_to_rad(config_.graph.match_sigma_deg),
                                         config_.graph.match_sigma_m) /
         variance_factor;
}

}  // namespace rankslam::slam
