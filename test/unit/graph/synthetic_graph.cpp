#include "synthetic_graph.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace rankslam::graph::testing {

Eigen::Isometry3d perturbed(const Eigen::Isometry3d& T, const Vector6d& xi) {
  Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d omega = xi.head<3>();
  if (omega.norm() > 0.0) {
    delta.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
  }
  delta.translation() = xi.tail<3>();
  return T * delta;
}

Vector6d log_so3_r3(const Eigen::Isometry3d& T) {
  const Eigen::AngleAxisd rotation(Eigen::Quaterniond(T.linear()).normalized());
  Vector6d xi;
  xi.head<3>() = rotation.angle() * rotation.axis();
  xi.tail<3>() = T.translation();
  return xi;
}

namespace {

Matrix6d information_of(double rotation_sigma_rad, double translation_sigma_m) {
  return information_from_matches(1, rotation_sigma_rad, translation_sigma_m);
}

Vector6d sample(std::mt19937_64& rng, double rotation_sigma_rad, double translation_sigma_m) {
  std::normal_distribution<double> unit(0.0, 1.0);
  Vector6d xi;
  for (int i = 0; i < 3; ++i) xi[i] = rotation_sigma_rad * unit(rng);
  for (int i = 3; i < 6; ++i) xi[i] = translation_sigma_m * unit(rng);
  return xi;
}

}  // namespace

Trajectory make_circle(const TrajectoryConfig& config) {
  Trajectory trajectory;
  std::mt19937_64 rng(config.seed);
  const int n = config.nodes;
  for (int i = 0; i < n; ++i) {
    const double angle = 2.0 * std::numbers::pi * i / n;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(angle + std::numbers::pi / 2.0, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(0.05 * std::sin(3.0 * angle), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(0.05 * std::cos(2.0 * angle), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() = Eigen::Vector3d(config.radius_m * std::cos(angle),
                                      config.radius_m * std::sin(angle),
                                      0.2 * std::sin(angle));
    trajectory.T_world_true.push_back(T);
  }
  trajectory.T_world_initial.push_back(trajectory.T_world_true.front());
  for (int i = 0; i + 1 < n; ++i) {
    const Eigen::Isometry3d T_true =
        trajectory.T_world_true[static_cast<std::size_t>(i)].inverse() *
        trajectory.T_world_true[static_cast<std::size_t>(i + 1)];
    Vector6d error = sample(rng, config.odometry_rotation_sigma_rad,
                            config.odometry_translation_sigma_m);
    error[2] += config.odometry_yaw_bias_rad;
    Edge edge;
    edge.from = i;
    edge.to = i + 1;
    edge.T_from_to = perturbed(T_true, error);
    edge.information =
        information_of(config.odometry_rotation_sigma_rad, config.odometry_translation_sigma_m);
    edge.kind = EdgeKind::kSequential;
    trajectory.edges.push_back(edge);
    trajectory.T_world_initial.push_back(trajectory.T_world_initial.back() * edge.T_from_to);
  }
  for (const auto& [from, to] : config.loops) {
    const Eigen::Isometry3d T_true =
        trajectory.T_world_true[static_cast<std::size_t>(from)].inverse() *
        trajectory.T_world_true[static_cast<std::size_t>(to)];
    Edge edge;
    edge.from = from;
    edge.to = to;
    edge.T_from_to = perturbed(
        T_true, sample(rng, config.loop_rotation_sigma_rad, config.loop_translation_sigma_m));
    edge.information =
        information_of(config.loop_rotation_sigma_rad, config.loop_translation_sigma_m);
    edge.kind = EdgeKind::kLoopClosure;
    trajectory.edges.push_back(edge);
  }
  return trajectory;
}

bool build_graph(const Trajectory& trajectory, bool start_at_truth, PoseGraph& graph,
                 const Capacity& capacity) {
  if (!graph.configure(capacity).empty()) return false;
  const auto& poses = start_at_truth ? trajectory.T_world_true : trajectory.T_world_initial;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (graph.add_node(poses[i]) != static_cast<int>(i)) return false;
  }
  for (const Edge& edge : trajectory.edges) {
    if (!graph.add_edge(edge)) return false;
  }
  return true;
}

double rms_position_error_m(const PoseGraph& graph, const Trajectory& trajectory) {
  double sum = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < trajectory.T_world_true.size(); ++i) {
    const int id = static_cast<int>(i);
    if (!graph.contains(id)) continue;
    sum += (graph.pose(id).translation() - trajectory.T_world_true[i].translation()).squaredNorm();
    ++count;
  }
  return count == 0 ? 0.0 : std::sqrt(sum / count);
}

double max_rotation_error_rad(const PoseGraph& graph, const Trajectory& trajectory) {
  double worst = 0.0;
  for (std::size_t i = 0; i < trajectory.T_world_true.size(); ++i) {
    const int id = static_cast<int>(i);
    if (!graph.contains(id)) continue;
    const Eigen::AngleAxisd error(Eigen::Quaterniond(
        graph.pose(id).linear().transpose() * trajectory.T_world_true[i].linear()));
    worst = std::max(worst, std::abs(error.angle()));
  }
  return worst;
}

}  // namespace rankslam::graph::testing
