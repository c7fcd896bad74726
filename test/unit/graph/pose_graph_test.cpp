// PoseGraph on synthetic trajectories with known ground truth: exact edges, drift corrected by
// a loop closure, a wrong low-information edge, node removal, capacity and input checks.

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <queue>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rankslam/graph/pose_graph.hpp"
#include "synthetic_graph.hpp"

namespace rankslam::graph {
namespace {

using testing::build_graph;
using testing::make_circle;
using testing::max_rotation_error_rad;
using testing::rms_position_error_m;
using testing::Trajectory;
using testing::TrajectoryConfig;

constexpr double kDegToRad = std::numbers::pi / 180.0;

Edge make_edge(int from, int to, const Eigen::Isometry3d& T_from_to,
               EdgeKind kind = EdgeKind::kSequential) {
  Edge edge;
  edge.from = from;
  edge.to = to;
  edge.T_from_to = T_from_to;
  edge.information = information_from_matches(100, 0.01, 0.01);
  edge.kind = kind;
  return edge;
}

// Every node reachable from the fixed node through the edges (either direction).
bool connected(const PoseGraph& graph) {
  const int slots = graph.capacity().max_nodes;
  std::vector<char> seen(static_cast<std::size_t>(slots), 0);
  std::queue<int> frontier;
  frontier.push(graph.fixed_node());
  seen[static_cast<std::size_t>(graph.fixed_node())] = 1;
  int reached = 1;
  while (!frontier.empty()) {
    const int node = frontier.front();
    frontier.pop();
    for (int i = 0; i < graph.edge_count(); ++i) {
      const Edge& edge = graph.edge(i);
      int other = -1;
      if (edge.from == node) other = edge.to;
      if (edge.to == node) other = edge.from;
      if (other < 0 || seen[static_cast<std::size_t>(other)] != 0) continue;
      seen[static_cast<std::size_t>(other)] = 1;
      ++reached;
      frontier.push(other);
    }
  }
  return reached == graph.node_count();
}

TEST(PoseGraph, ConfigureNamesTheBadField) {
  PoseGraph graph;
  EXPECT_NE(graph.configure({1, 10}).find("graph.max_nodes"), std::string::npos);
  EXPECT_NE(graph.configure({70000, 10}).find("graph.max_nodes"), std::string::npos);
  EXPECT_NE(graph.configure({10, 0}).find("graph.max_edges"), std::string::npos);
  EXPECT_FALSE(graph.configured());
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), -1);
  EXPECT_FALSE(graph.optimize().ok);
  EXPECT_EQ(graph.configure({10, 20}), "");
  EXPECT_TRUE(graph.configured());
}

TEST(PoseGraph, ExactEdgesGiveZeroCostAndTheGroundTruth) {
  TrajectoryConfig config;
  config.odometry_yaw_bias_rad = 0.0;
  config.odometry_rotation_sigma_rad = 1e-12;  // information from these; noise negligible
  config.odometry_translation_sigma_m = 1e-12;
  config.loop_rotation_sigma_rad = 1e-12;
  config.loop_translation_sigma_m = 1e-12;
  Trajectory trajectory = make_circle(config);
  // Exact measurements, sensible information.
  for (Edge& edge : trajectory.edges) {
    edge.T_from_to = trajectory.T_world_true[static_cast<std::size_t>(edge.from)].inverse() *
                     trajectory.T_world_true[static_cast<std::size_t>(edge.to)];
    edge.information = information_from_matches(50, 0.01, 0.01);
  }

  PoseGraph at_truth;
  ASSERT_TRUE(build_graph(trajectory, true, at_truth));
  EXPECT_LT(at_truth.cost(), 1e-20);
  const OptimizeSummary stay = at_truth.optimize();
  EXPECT_TRUE(stay.ok) << stay.message;
  EXPECT_LT(stay.initial_cost, 1e-20);
  EXPECT_LT(stay.final_cost, 1e-20);
  EXPECT_LT(rms_position_error_m(at_truth, trajectory), 1e-9);

  // From poses perturbed by up to ~0.3 m and ~6°, back to the ground truth.
  PoseGraph perturbed;
  ASSERT_TRUE(build_graph(trajectory, true, perturbed));
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int id = 1; id < perturbed.node_count(); ++id) {
    Vector6d xi;
    for (int k = 0; k < 3; ++k) xi[k] = 0.06 * uniform(rng);
    for (int k = 3; k < 6; ++k) xi[k] = 0.17 * uniform(rng);
    ASSERT_TRUE(perturbed.set_pose(id, testing::perturbed(perturbed.pose(id), xi)));
  }
  const OptimizeSummary summary = perturbed.optimize(50);
  std::printf("exact edges from perturbed poses: cost %.3g -> %.3g in %d iterations, %.2f ms\n",
              summary.initial_cost, summary.final_cost, summary.iterations, summary.solve_ms);
  EXPECT_TRUE(summary.ok) << summary.message;
  EXPECT_GT(summary.initial_cost, 1.0);
  EXPECT_LT(summary.final_cost, 1e-12);
  EXPECT_LT(rms_position_error_m(perturbed, trajectory), 1e-6);
  EXPECT_LT(max_rotation_error_rad(perturbed, trajectory), 1e-6);
}

TEST(PoseGraph, LoopClosureRemovesMostOfTheDrift) {
  const Trajectory trajectory = make_circle(TrajectoryConfig{});
  PoseGraph graph;
  ASSERT_TRUE(build_graph(trajectory, false, graph));
  const double before_m = rms_position_error_m(graph, trajectory);
  const double before_rad = max_rotation_error_rad(graph, trajectory);
  const OptimizeSummary summary = graph.optimize();
  const double after_m = rms_position_error_m(graph, trajectory);
  const double after_rad = max_rotation_error_rad(graph, trajectory);
  std::printf("40-node circle, 1 loop closure: RMS position error %.4f m -> %.4f m (x%.1f), "
              "max rotation error %.2f deg -> %.2f deg; cost %.4g -> %.4g, %d iterations, "
              "%.2f ms (%.*s)\n",
              before_m, after_m, before_m / after_m, before_rad / kDegToRad,
              after_rad / kDegToRad, summary.initial_cost, summary.final_cost,
              summary.iterations, summary.solve_ms, static_cast<int>(summary.message.size()),
              summary.message.data());
  ASSERT_TRUE(summary.ok) << summary.message;
  EXPECT_LT(summary.final_cost, summary.initial_cost);
  EXPECT_GT(before_m, 0.5);  // the drift is real
  EXPECT_LT(after_m, before_m / 10.0);
  EXPECT_LT(after_rad, before_rad / 5.0);
  // The fixed node (the gauge) did not move.
  EXPECT_TRUE(graph.pose(0).isApprox(trajectory.T_world_initial[0], 1e-12));
  EXPECT_NEAR(graph.cost(), summary.final_cost, 1e-9 * (1.0 + summary.final_cost));
}

// Held nodes (a loaded map's key-frames) stay where they are, as the fixed one does; the rest
// still take the loop closure's correction; a copy holds the same nodes, a removed one is let go.
TEST(PoseGraph, HeldNodesStayWhereTheyAreAndTheRestMove) {
  const Trajectory trajectory = make_circle(TrajectoryConfig{});
  PoseGraph graph;
  ASSERT_TRUE(build_graph(trajectory, false, graph));
  std::vector<Eigen::Isometry3d> before;
  for (int id = 0; id < 10; ++id) {
    ASSERT_TRUE(graph.hold(id));
    before.push_back(graph.pose(id));
  }
  EXPECT_FALSE(graph.hold(graph.capacity().max_nodes));
  EXPECT_TRUE(graph.held(3));
  EXPECT_FALSE(graph.held(10));
  const double before_m = rms_position_error_m(graph, trajectory);
  const Eigen::Isometry3d last_before = graph.pose(graph.node_count() - 1);
  PoseGraph copy;
  ASSERT_EQ(copy.configure(graph.capacity()), "");
  ASSERT_TRUE(copy.copy_from(graph));
  const OptimizeSummary summary = copy.optimize();
  ASSERT_TRUE(summary.ok) << summary.message;
  for (int id = 0; id < 10; ++id) EXPECT_TRUE(copy.pose(id).isApprox(before[static_cast<std::size_t>(id)], 1e-12)) << id;
  EXPECT_FALSE(copy.pose(copy.node_count() - 1).isApprox(last_before, 1e-6)) << "the other nodes did not move";
  EXPECT_LT(rms_position_error_m(copy, trajectory), before_m);
  ASSERT_TRUE(graph.remove_node(5));
  EXPECT_FALSE(graph.held(5));
}

TEST(PoseGraph, WrongEdgeWithLowInformationBarelyMovesThePoses) {
  TrajectoryConfig config;
  config.odometry_yaw_bias_rad = 0.0;
  const Trajectory trajectory = make_circle(config);
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.linear() = Eigen::AngleAxisd(20.0 * kDegToRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  offset.translation() = Eigen::Vector3d(1.0, -0.5, 0.2);
  Edge wrong = make_edge(10, 30,
                         trajectory.T_world_true[10].inverse() * trajectory.T_world_true[30] *
                             offset,
                         EdgeKind::kLoopClosure);

  PoseGraph reference;
  ASSERT_TRUE(build_graph(trajectory, false, reference));
  ASSERT_TRUE(reference.optimize().ok);

  const auto largest_shift_m = [&](double information_scale) {
    PoseGraph graph;
    EXPECT_TRUE(build_graph(trajectory, false, graph));
    wrong.information = information_scale * Matrix6d::Identity();
    EXPECT_TRUE(graph.add_edge(wrong));
    EXPECT_TRUE(graph.optimize().ok);
    double largest = 0.0;
    for (int id = 0; id < graph.node_count(); ++id) {
      largest = std::max(largest,
                         (graph.pose(id).translation() - reference.pose(id).translation()).norm());
    }
    return largest;
  };
  // The odometry's information is ~1e4 (σ = 1 cm, 3 mrad); a weak wrong edge (1 match at σ=1)
  // should shift nothing by more than a few millimetres, a strong one (σ = 1 cm) a lot.
  const double weak_shift_m = largest_shift_m(1.0);
  const double strong_shift_m = largest_shift_m(1e4);
  std::printf("wrong loop edge (1 m, 20 deg off): largest shift %.4f m at information 1, "
              "%.4f m at information 1e4\n",
              weak_shift_m, strong_shift_m);
  EXPECT_LT(weak_shift_m, 0.005);
  EXPECT_GT(strong_shift_m, 0.1);
}

TEST(PoseGraph, RemoveNodeComposesAChainExactly) {
  PoseGraph graph;
  ASSERT_EQ(graph.configure({8, 16}), "");
  Eigen::Isometry3d T_a_id = Eigen::Isometry3d::Identity();
  T_a_id.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T_a_id.translation() = Eigen::Vector3d(0.5, -0.2, 0.1);
  Eigen::Isometry3d T_id_b = Eigen::Isometry3d::Identity();
  T_id_b.linear() = Eigen::AngleAxisd(-0.4, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  T_id_b.translation() = Eigen::Vector3d(0.1, 0.7, -0.3);
  const int a = graph.add_node(Eigen::Isometry3d::Identity());
  const int id = graph.add_node(T_a_id);
  const int b = graph.add_node(T_a_id * T_id_b);
  ASSERT_TRUE(graph.add_edge(make_edge(a, id, T_a_id)));
  // Stored the other way round, so remove_node has to invert it.
  ASSERT_TRUE(graph.add_edge(make_edge(b, id, T_id_b.inverse(), EdgeKind::kLoopClosure)));
  ASSERT_TRUE(graph.remove_node(id));
  EXPECT_FALSE(graph.contains(id));
  ASSERT_EQ(graph.edge_count(), 1);
  const Edge& composed = graph.edge(0);
  const bool forward = composed.from == a;
  EXPECT_TRUE(forward ? composed.to == b : (composed.from == b && composed.to == a));
  const Eigen::Isometry3d T_a_b = forward ? composed.T_from_to : composed.T_from_to.inverse();
  EXPECT_TRUE(T_a_b.isApprox(T_a_id * T_id_b, 1e-12));
  EXPECT_EQ(composed.kind, EdgeKind::kLoopClosure);
  EXPECT_LT(graph.cost(), 1e-20);
}

TEST(PoseGraph, ComposedCovarianceMatchesSampling) {
  // Monte Carlo check of the first-order propagation in remove_node(): sample both
  // measurements' errors, compose, and compare the spread of log(Ẑ_ab⁻¹·Z_ab) with the
  // covariance of the composed edge.
  Eigen::Isometry3d T_a_id = Eigen::Isometry3d::Identity();
  T_a_id.linear() = Eigen::AngleAxisd(0.5, Eigen::Vector3d(0, 0, 1)).toRotationMatrix();
  T_a_id.translation() = Eigen::Vector3d(1.0, 0.2, 0.0);
  Eigen::Isometry3d T_id_b = Eigen::Isometry3d::Identity();
  T_id_b.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 0, 1).normalized()).toRotationMatrix();
  T_id_b.translation() = Eigen::Vector3d(0.3, 1.5, -0.4);
  Vector6d sigma_a_id;
  sigma_a_id << 0.01, 0.02, 0.015, 0.02, 0.01, 0.03;
  Vector6d sigma_id_b;
  sigma_id_b << 0.02, 0.01, 0.01, 0.01, 0.02, 0.01;

  PoseGraph graph;
  ASSERT_EQ(graph.configure({4, 4}), "");
  const int a = graph.add_node(Eigen::Isometry3d::Identity());
  const int id = graph.add_node(T_a_id);
  const int b = graph.add_node(T_a_id * T_id_b);
  Edge first = make_edge(a, id, T_a_id);
  first.information = sigma_a_id.cwiseAbs2().cwiseInverse().asDiagonal();
  Edge second = make_edge(id, b, T_id_b);
  second.information = sigma_id_b.cwiseAbs2().cwiseInverse().asDiagonal();
  ASSERT_TRUE(graph.add_edge(first));
  ASSERT_TRUE(graph.add_edge(second));
  ASSERT_TRUE(graph.remove_node(id));
  ASSERT_EQ(graph.edge_count(), 1);
  const Edge& composed = graph.edge(0);
  // Compare in the a→b direction.
  ASSERT_TRUE(composed.from == a || composed.from == b);
  Matrix6d covariance = composed.information.inverse();
  if (composed.from == b) {
    Matrix6d ad = Matrix6d::Zero();  // Ad(T_b_a⁻¹) maps b→a errors into a→b ones
    const Eigen::Isometry3d T_b_a = composed.T_from_to;
    const Eigen::Matrix3d R = T_b_a.linear();
    Eigen::Matrix3d t_hat;
    const Eigen::Vector3d t = T_b_a.translation();
    t_hat << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
    ad.topLeftCorner<3, 3>() = R;
    ad.bottomRightCorner<3, 3>() = R;
    ad.bottomLeftCorner<3, 3>() = t_hat * R;
    covariance = ad * covariance * ad.transpose();
  }

  std::mt19937_64 rng(3);
  std::normal_distribution<double> unit(0.0, 1.0);
  constexpr int kSamples = 40000;
  Matrix6d sampled = Matrix6d::Zero();
  const Eigen::Isometry3d T_a_b = T_a_id * T_id_b;
  for (int s = 0; s < kSamples; ++s) {
    Vector6d e1;
    Vector6d e2;
    for (int k = 0; k < 6; ++k) e1[k] = sigma_a_id[k] * unit(rng);
    for (int k = 0; k < 6; ++k) e2[k] = sigma_id_b[k] * unit(rng);
    const Eigen::Isometry3d sample =
        testing::perturbed(T_a_id, e1) * testing::perturbed(T_id_b, e2);
    const Vector6d xi = testing::log_so3_r3(T_a_b.inverse() * sample);
    sampled += xi * xi.transpose();
  }
  sampled /= kSamples;
  // Diagonal within 5 % (sampling error ~1 % at 40 000 samples, linearisation a little more),
  // correlations within 0.05.
  for (int r = 0; r < 6; ++r) {
    EXPECT_NEAR(covariance(r, r) / sampled(r, r), 1.0, 0.05) << "row " << r;
    for (int c = 0; c < r; ++c) {
      const double predicted = covariance(r, c) / std::sqrt(covariance(r, r) * covariance(c, c));
      const double observed = sampled(r, c) / std::sqrt(sampled(r, r) * sampled(c, c));
      EXPECT_NEAR(predicted, observed, 0.05) << "(" << r << ", " << c << ")";
    }
  }
}

TEST(PoseGraph, RemoveNodeKeepsTheGraphConnectedAndTheSolutionClose) {
  TrajectoryConfig config;
  config.loops = {{39, 0}, {20, 0}, {30, 10}};
  const Trajectory trajectory = make_circle(config);
  PoseGraph full;
  ASSERT_TRUE(build_graph(trajectory, false, full));
  PoseGraph thinned;
  ASSERT_TRUE(build_graph(trajectory, false, thinned));
  // Retire every third node, the loop-closure ends 0, 10, 20 and 30 included (0 is the fixed one).
  int removed = 0;
  for (int id = 0; id < 40; id += 3) {
    ASSERT_TRUE(thinned.remove_node(id));
    ++removed;
    EXPECT_TRUE(connected(thinned)) << "after removing node " << id;
  }
  for (int id : {10, 20}) {
    ASSERT_TRUE(thinned.remove_node(id));
    ++removed;
    EXPECT_TRUE(connected(thinned)) << "after removing node " << id;
  }
  EXPECT_FALSE(thinned.remove_node(3));  // already gone
  EXPECT_EQ(thinned.node_count(), 40 - removed);
  EXPECT_LT(thinned.edge_count(), full.edge_count());
  EXPECT_NE(thinned.fixed_node(), 0);
  EXPECT_TRUE(thinned.contains(thinned.fixed_node()));

  ASSERT_TRUE(full.optimize().ok);
  const OptimizeSummary summary = thinned.optimize();
  ASSERT_TRUE(summary.ok) << summary.message;
  // The gauge moved to another node, which still sits at its dead-reckoned pose: compare
  // shapes after a least-squares rigid alignment (Umeyama) of the remaining nodes' positions.
  const auto aligned_rms_m = [&](const PoseGraph& graph, const auto& target_position) {
    Eigen::Matrix3Xd from(3, graph.node_count());
    Eigen::Matrix3Xd to(3, graph.node_count());
    int column = 0;
    for (int id = 0; id < 40; ++id) {
      if (!thinned.contains(id)) continue;
      from.col(column) = graph.pose(id).translation();
      to.col(column) = target_position(id);
      ++column;
    }
    const Eigen::Matrix4d align = Eigen::umeyama(from.leftCols(column), to.leftCols(column), false);
    const Eigen::Matrix3Xd moved =
        (align.topLeftCorner<3, 3>() * from.leftCols(column)).colwise() +
        align.topRightCorner<3, 1>();
    return std::sqrt((moved - to.leftCols(column)).colwise().squaredNorm().mean());
  };
  const auto full_position = [&](int id) { return Eigen::Vector3d(full.pose(id).translation()); };
  const auto true_position = [&](int id) {
    return Eigen::Vector3d(trajectory.T_world_true[static_cast<std::size_t>(id)].translation());
  };
  const double thinned_to_full_m = aligned_rms_m(thinned, full_position);
  const double full_to_truth_m = aligned_rms_m(full, true_position);
  const double thinned_to_truth_m = aligned_rms_m(thinned, true_position);
  std::printf("%d of 40 nodes removed: %d edges left of %d; on the remaining nodes, aligned RMS "
              "position difference thinned-full %.4f m, full-truth %.4f m, thinned-truth %.4f m\n",
              removed, thinned.edge_count(), full.edge_count(), thinned_to_full_m,
              full_to_truth_m, thinned_to_truth_m);
  // Removing nodes changes the answer by less than the answer's own error, and does not make
  // it much worse against the truth.
  EXPECT_LT(thinned_to_full_m, full_to_truth_m);
  EXPECT_LT(thinned_to_truth_m, 1.5 * full_to_truth_m);
}

TEST(PoseGraph, RemovedSlotsAreReusedWithANewGeneration) {
  PoseGraph graph;
  ASSERT_EQ(graph.configure({4, 8}), "");
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), 0);
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), 1);
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), 2);
  EXPECT_EQ(graph.fixed_node(), 0);
  EXPECT_EQ(graph.generation(1), 1u);
  ASSERT_TRUE(graph.remove_node(1));
  EXPECT_EQ(graph.generation(1), 1u);
  EXPECT_FALSE(graph.contains(1));
  EXPECT_TRUE(graph.pose(1).isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), 1);
  EXPECT_EQ(graph.generation(1), 2u);
  EXPECT_TRUE(graph.set_fixed(2));
  EXPECT_EQ(graph.fixed_node(), 2);
  EXPECT_FALSE(graph.set_fixed(3));
  EXPECT_FALSE(graph.set_fixed(-1));
  EXPECT_EQ(graph.fixed_node(), 2);
  // The fixed node without edges: the lowest remaining node takes over.
  ASSERT_TRUE(graph.remove_node(2));
  EXPECT_EQ(graph.fixed_node(), 0);
}

TEST(PoseGraph, FullCapacityRefusesWithoutChange) {
  PoseGraph graph;
  ASSERT_EQ(graph.configure({3, 2}), "");
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), 0);
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), 1);
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), 2);
  EXPECT_EQ(graph.add_node(Eigen::Isometry3d::Identity()), -1);
  EXPECT_EQ(graph.node_count(), 3);
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  EXPECT_TRUE(graph.add_edge(make_edge(0, 1, I)));
  EXPECT_TRUE(graph.add_edge(make_edge(1, 2, I)));
  EXPECT_FALSE(graph.add_edge(make_edge(0, 2, I)));
  EXPECT_EQ(graph.edge_count(), 2);
  // Removing the middle node frees a slot and composes its two edges into one.
  ASSERT_TRUE(graph.remove_node(1));
  EXPECT_EQ(graph.edge_count(), 1);
  EXPECT_EQ(graph.add_node(I), 1);
  EXPECT_TRUE(graph.add_edge(make_edge(0, 1, I)));
  EXPECT_FALSE(graph.add_edge(make_edge(1, 2, I)));
}

TEST(PoseGraph, RejectsNonFiniteAndInvalidInput) {
  PoseGraph graph;
  ASSERT_EQ(graph.configure({8, 8}), "");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  Eigen::Isometry3d bad = Eigen::Isometry3d::Identity();
  bad.translation().x() = nan;
  EXPECT_EQ(graph.add_node(bad), -1);
  bad = Eigen::Isometry3d::Identity();
  bad.linear()(0, 0) = inf;
  EXPECT_EQ(graph.add_node(bad), -1);
  Eigen::Isometry3d sheared = Eigen::Isometry3d::Identity();
  sheared.linear()(0, 1) = 0.1;
  EXPECT_EQ(graph.add_node(sheared), -1);
  EXPECT_EQ(graph.node_count(), 0);

  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  ASSERT_EQ(graph.add_node(I), 0);
  ASSERT_EQ(graph.add_node(I), 1);
  EXPECT_FALSE(graph.set_pose(1, bad));

  Edge edge = make_edge(0, 1, I);
  edge.T_from_to.translation().z() = nan;
  EXPECT_FALSE(graph.add_edge(edge));
  edge = make_edge(0, 1, sheared);
  EXPECT_FALSE(graph.add_edge(edge));
  edge = make_edge(0, 1, I);
  edge.information(2, 2) = inf;
  EXPECT_FALSE(graph.add_edge(edge));
  edge = make_edge(0, 1, I);
  edge.information(3, 3) = nan;
  EXPECT_FALSE(graph.add_edge(edge));
  edge = make_edge(0, 1, I);
  edge.information(0, 0) = -1.0;  // not positive definite
  EXPECT_FALSE(graph.add_edge(edge));
  edge = make_edge(0, 1, I);
  edge.information = Matrix6d::Zero();
  EXPECT_FALSE(graph.add_edge(edge));
  edge = make_edge(0, 1, I);
  edge.information(0, 1) = 5.0;  // not symmetric
  EXPECT_FALSE(graph.add_edge(edge));
  EXPECT_FALSE(graph.add_edge(make_edge(0, 2, I)));   // unknown id
  EXPECT_FALSE(graph.add_edge(make_edge(-1, 1, I)));  // unknown id
  EXPECT_FALSE(graph.add_edge(make_edge(1, 1, I)));   // self-loop
  EXPECT_EQ(graph.edge_count(), 0);
  EXPECT_FALSE(graph.remove_node(5));
  EXPECT_FALSE(graph.remove_node(-3));

  EXPECT_TRUE(information_from_matches(0, 0.01, 0.01).isZero());
  EXPECT_TRUE(information_from_matches(10, -0.01, 0.01).isZero());
  EXPECT_TRUE(information_from_matches(10, 0.01, nan).isZero());
  const Matrix6d information = information_from_matches(100, 0.01, 0.02);
  EXPECT_NEAR(information(0, 0), 100.0 / (0.01 * 0.01), 1e-6);
  EXPECT_NEAR(information(5, 5), 100.0 / (0.02 * 0.02), 1e-6);
  EXPECT_TRUE(graph.add_edge(make_edge(0, 1, I)));
}

TEST(PoseGraph, CopyKeepsIdsAndNeedsRoom) {
  const Trajectory trajectory = make_circle(TrajectoryConfig{});
  PoseGraph source;
  ASSERT_TRUE(build_graph(trajectory, false, source));
  ASSERT_TRUE(source.remove_node(5));
  PoseGraph copy;
  ASSERT_EQ(copy.configure(Capacity{}), "");
  ASSERT_TRUE(copy.copy_from(source));
  EXPECT_EQ(copy.node_count(), source.node_count());
  EXPECT_EQ(copy.edge_count(), source.edge_count());
  EXPECT_FALSE(copy.contains(5));
  EXPECT_TRUE(copy.pose(7).isApprox(source.pose(7), 0.0));
  EXPECT_DOUBLE_EQ(copy.cost(), source.cost());
  const OptimizeSummary a = source.optimize();
  const OptimizeSummary b = copy.optimize();
  EXPECT_DOUBLE_EQ(a.final_cost, b.final_cost);

  PoseGraph small;
  ASSERT_EQ(small.configure({16, 2048}), "");
  EXPECT_FALSE(small.copy_from(source));
  EXPECT_EQ(small.node_count(), 0);
}

}  // namespace
}  // namespace rankslam::graph
