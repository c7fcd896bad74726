// Fixed memory on the tracking thread: after configure(), adding and removing nodes and edges,
// copying the graph, submitting it to the background optimiser and taking the result allocate
// nothing. The counter sees every thread, so each count is taken while no solve runs (the
// optimiser is paused around submit()); the solve itself allocates inside Ceres, and the
// counter must see that, or the zeros would prove nothing.

#include <chrono>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "rankslam/graph/background_optimizer.hpp"
#include "rankslam/graph/pose_graph.hpp"
#include "synthetic_graph.hpp"

namespace rankslam::graph {
namespace {

using namespace std::chrono_literals;
using test_support::CountAllocations;

TEST(GraphAllocations, NoneOnTheTrackingThreadAfterConfigure) {
  testing::TrajectoryConfig config;
  config.loops = {{39, 0}, {20, 0}, {30, 10}};
  const testing::Trajectory trajectory = testing::make_circle(config);
  PoseGraph graph;
  ASSERT_EQ(graph.configure(Capacity{}), "");
  PoseGraph copy;
  ASSERT_EQ(copy.configure(Capacity{}), "");
  BackgroundOptimizer optimizer;
  ASSERT_EQ(optimizer.configure(Capacity{}), "");
  OptimizedPoses result;
  ASSERT_EQ(result.configure(Capacity{}), "");

  long allocations = 0;
  {
    CountAllocations count;
    for (const Eigen::Isometry3d& T : trajectory.T_world_initial) {
      if (graph.add_node(T) < 0) ADD_FAILURE() << "add_node";
    }
    for (const Edge& edge : trajectory.edges) {
      if (!graph.add_edge(edge)) ADD_FAILURE() << "add_edge";
    }
    if (!graph.remove_node(20) || !graph.remove_node(0) || !graph.remove_node(31)) {
      ADD_FAILURE() << "remove_node";
    }
    if (graph.add_node(trajectory.T_world_initial[20]) != 0) ADD_FAILURE() << "slot reuse";
    if (!graph.set_fixed(1) || !graph.set_pose(2, trajectory.T_world_true[2])) {
      ADD_FAILURE() << "set_fixed / set_pose";
    }
    if (!copy.copy_from(graph)) ADD_FAILURE() << "copy_from";
    volatile double sink = graph.cost();
    (void)sink;
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(graph.node_count(), 38);

  optimizer.pause();
  {
    CountAllocations count;
    if (!optimizer.submit(graph)) ADD_FAILURE() << "submit";
    if (optimizer.submit(graph)) ADD_FAILURE() << "second submit accepted";
    if (!optimizer.busy()) ADD_FAILURE() << "busy";
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0) << "submit";

  long solve_allocations = 0;
  {
    CountAllocations count;
    optimizer.resume();
    ASSERT_TRUE(optimizer.wait_until_idle(60s));
    solve_allocations = count.allocations();
  }
  EXPECT_GT(solve_allocations, 0) << "the counter must see Ceres' allocations";

  {
    CountAllocations count;
    if (!optimizer.take_result(result)) ADD_FAILURE() << "take_result";
    if (apply_optimized_poses(result, graph) != graph.node_count()) ADD_FAILURE() << "apply";
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0) << "take_result";
  EXPECT_TRUE(result.summary().ok);
}

}  // namespace
}  // namespace rankslam::graph
