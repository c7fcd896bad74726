// BackgroundOptimizer: the same result as PoseGraph::optimize(), submit() refuses instead of
// waiting while a solve is queued or running, results map back by node id and generation, and
// destruction stops a long solve.

#include <chrono>
#include <cstdio>

#include <gtest/gtest.h>

#include "rankslam/graph/background_optimizer.hpp"
#include "rankslam/graph/pose_graph.hpp"
#include "synthetic_graph.hpp"

namespace rankslam::graph {
namespace {

using namespace std::chrono_literals;
using testing::build_graph;
using testing::make_circle;
using testing::Trajectory;
using testing::TrajectoryConfig;

// A graph whose solve takes long enough (tens of iterations over 256 nodes and 2048 edges) to
// be observed while it runs.
Trajectory large_trajectory() {
  TrajectoryConfig config;
  config.nodes = 256;
  config.radius_m = 10.0;
  config.odometry_yaw_bias_rad = 0.02;
  config.loops.clear();
  for (int i = 0; i + 20 < config.nodes; ++i) {
    for (int step : {5, 7, 11, 13, 17, 19, 20}) {
      if (i + step < config.nodes) config.loops.emplace_back(i + step, i);
    }
  }
  return make_circle(config);
}

TEST(BackgroundOptimizer, GivesTheSameResultAsOptimize) {
  const Trajectory trajectory = make_circle(TrajectoryConfig{});
  PoseGraph graph;
  ASSERT_TRUE(build_graph(trajectory, false, graph));
  ASSERT_TRUE(graph.remove_node(17));  // a hole in the ids

  BackgroundOptimizer optimizer;
  ASSERT_EQ(optimizer.configure(Capacity{}), "");
  OptimizedPoses result;
  ASSERT_EQ(result.configure(Capacity{}), "");
  EXPECT_FALSE(optimizer.take_result(result));  // nothing submitted yet
  ASSERT_TRUE(optimizer.submit(graph, 20));
  ASSERT_TRUE(optimizer.wait_until_idle(60s));
  ASSERT_TRUE(optimizer.take_result(result));
  EXPECT_FALSE(optimizer.take_result(result));  // taken once only
  EXPECT_EQ(result.submission(), 1u);
  EXPECT_EQ(optimizer.completed(), 1u);

  PoseGraph direct;
  ASSERT_EQ(direct.configure(Capacity{}), "");
  ASSERT_TRUE(direct.copy_from(graph));
  const OptimizeSummary summary = direct.optimize(20);
  ASSERT_TRUE(summary.ok);
  ASSERT_TRUE(result.summary().ok) << result.summary().message;
  EXPECT_EQ(result.summary().iterations, summary.iterations);
  EXPECT_DOUBLE_EQ(result.summary().final_cost, summary.final_cost);
  for (int id = 0; id < Capacity{}.max_nodes; ++id) {
    ASSERT_EQ(result.contains(id), direct.contains(id)) << id;
    if (!direct.contains(id)) continue;
    EXPECT_TRUE(result.pose(id).isApprox(direct.pose(id), 1e-12)) << id;
    EXPECT_EQ(result.generation(id), direct.generation(id));
  }

  // The caller's graph was not touched; applying the result makes it the optimised one.
  EXPECT_GT(graph.cost(), summary.final_cost);
  EXPECT_EQ(apply_optimized_poses(result, graph), graph.node_count());
  EXPECT_NEAR(graph.cost(), summary.final_cost, 1e-9 * (1.0 + summary.final_cost));
}

TEST(BackgroundOptimizer, ResultSkipsSlotsReusedSinceSubmission) {
  const Trajectory trajectory = make_circle(TrajectoryConfig{});
  PoseGraph graph;
  ASSERT_TRUE(build_graph(trajectory, false, graph));
  BackgroundOptimizer optimizer;
  ASSERT_EQ(optimizer.configure(Capacity{}), "");
  OptimizedPoses result;
  ASSERT_EQ(result.configure(Capacity{}), "");
  ASSERT_TRUE(optimizer.submit(graph));
  // While it solves, the tracking thread retires node 12 and a new key-frame takes its slot.
  ASSERT_TRUE(graph.remove_node(12));
  const Eigen::Isometry3d new_pose = Eigen::Isometry3d(Eigen::Translation3d(9.0, 9.0, 9.0));
  ASSERT_EQ(graph.add_node(new_pose), 12);
  const int added = graph.add_node(new_pose);
  ASSERT_EQ(added, 40);
  ASSERT_TRUE(optimizer.wait_until_idle(60s));
  ASSERT_TRUE(optimizer.take_result(result));
  EXPECT_TRUE(result.contains(12));
  EXPECT_FALSE(result.contains(40));
  EXPECT_EQ(apply_optimized_poses(result, graph), 40 - 1);
  EXPECT_TRUE(graph.pose(12).isApprox(new_pose));
  EXPECT_TRUE(graph.pose(40).isApprox(new_pose));
  EXPECT_TRUE(graph.pose(13).isApprox(result.pose(13)));
}

TEST(BackgroundOptimizer, SubmitRefusesInsteadOfWaiting) {
  const Trajectory trajectory = large_trajectory();
  PoseGraph graph;
  ASSERT_TRUE(build_graph(trajectory, false, graph, Capacity{}));
  ASSERT_EQ(graph.edge_count(), static_cast<int>(trajectory.edges.size()));

  BackgroundOptimizer optimizer;
  ASSERT_EQ(optimizer.configure(Capacity{}), "");
  EXPECT_FALSE(optimizer.busy());

  // Queued behind a pause: the second submit is refused, the first still waits.
  optimizer.pause();
  ASSERT_TRUE(optimizer.submit(graph, 200));
  EXPECT_TRUE(optimizer.busy());
  EXPECT_FALSE(optimizer.submit(graph, 200));
  EXPECT_FALSE(optimizer.wait_until_idle(50ms));  // paused: nothing runs
  EXPECT_EQ(optimizer.completed(), 0u);

  // Running: submit() returns false while the solve goes on, and the solve is still running
  // when it has returned (it did not wait for it).
  optimizer.resume();
  int refused_while_running = 0;
  unsigned accepted = 1;
  const auto start = std::chrono::steady_clock::now();
  while (optimizer.busy()) {
    // The solve may end between busy() and submit(): then the submit is taken and numbered.
    if (optimizer.submit(graph, 200)) {
      ++accepted;
    } else if (optimizer.completed() == 0 && optimizer.busy()) {
      ++refused_while_running;
    }
    std::this_thread::sleep_for(1ms);
  }
  const double solve_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  OptimizedPoses result;
  ASSERT_EQ(result.configure(Capacity{}), "");
  ASSERT_TRUE(optimizer.take_result(result));
  std::printf("256 nodes, %d edges: background solve %.1f ms (%d iterations), %d submits "
              "refused while it ran\n",
              graph.edge_count(), solve_ms, result.summary().iterations, refused_while_running);
  EXPECT_TRUE(result.summary().ok) << result.summary().message;
  EXPECT_GE(refused_while_running, 1);
  EXPECT_EQ(result.submission(), accepted);
  // Idle again: the next submit is accepted and numbered.
  ASSERT_TRUE(optimizer.submit(graph, 1));
  ASSERT_TRUE(optimizer.wait_until_idle(60s));
  ASSERT_TRUE(optimizer.take_result(result));
  EXPECT_EQ(result.submission(), accepted + 1);
}

TEST(BackgroundOptimizer, RefusesWhatDoesNotFit) {
  BackgroundOptimizer optimizer;
  PoseGraph graph;
  ASSERT_EQ(graph.configure({64, 64}), "");
  EXPECT_FALSE(optimizer.submit(graph));  // not configured
  EXPECT_NE(optimizer.configure({1, 1}).find("graph.max_nodes"), std::string::npos);
  ASSERT_EQ(optimizer.configure({32, 64}), "");
  EXPECT_NE(optimizer.configure({32, 64}), "");  // once only
  EXPECT_FALSE(optimizer.submit(graph));  // 64 node slots do not fit in 32
  EXPECT_FALSE(optimizer.busy());
  PoseGraph fits;
  ASSERT_EQ(fits.configure({32, 64}), "");
  EXPECT_FALSE(optimizer.submit(fits, 0));  // max_iterations below 1
  ASSERT_TRUE(optimizer.submit(fits));
  ASSERT_TRUE(optimizer.wait_until_idle(60s));
  OptimizedPoses too_small;
  ASSERT_EQ(too_small.configure({16, 16}), "");
  EXPECT_FALSE(optimizer.take_result(too_small));
}

TEST(BackgroundOptimizer, DestructionStopsALongSolve) {
  const Trajectory trajectory = large_trajectory();
  PoseGraph graph;
  ASSERT_TRUE(build_graph(trajectory, false, graph, Capacity{}));
  const auto start = std::chrono::steady_clock::now();
  {
    BackgroundOptimizer optimizer;
    ASSERT_EQ(optimizer.configure(Capacity{}), "");
    ASSERT_TRUE(optimizer.submit(graph, 100000));
    std::this_thread::sleep_for(20ms);
    EXPECT_TRUE(optimizer.busy());
  }
  std::printf("destroyed during a solve after %.1f ms\n",
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                  .count());
}

}  // namespace
}  // namespace rankslam::graph
