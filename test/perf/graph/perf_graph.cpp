// Pose-graph optimisation time on synthetic circles (test/unit/graph/synthetic_graph.hpp):
// dead-reckoned start with a constant yaw bias, odometry edges plus loop closures.
//   Optimize/200/400    200 nodes, 400 edges (199 odometry + 201 loop closures), 20 iterations
//   Optimize/256/2048   the default capacity, full
// and the tracking-thread side: copying a full graph (what BackgroundOptimizer::submit does)
// and retiring a node.
//   perf_graph [benchmark flags]

#include <utility>
#include <vector>

#include <benchmark/benchmark.h>

#include "rankslam/graph/pose_graph.hpp"
#include "synthetic_graph.hpp"

namespace {

namespace graph = rankslam::graph;
namespace testing = rankslam::graph::testing;

// n nodes on a circle, n-1 odometry edges (yaw bias 3 mrad per edge), the loop closure from the
// last node to the first, and loop closures from node i to i-s for the strides 3, 5, 7, ...
// until there are `edges` edges.
testing::Trajectory make_trajectory(int nodes, int edges) {
  testing::TrajectoryConfig config;
  config.nodes = nodes;
  config.radius_m = 8.0;
  config.odometry_yaw_bias_rad = 0.003;
  config.loops = {{nodes - 1, 0}};
  int needed = edges - nodes;
  for (int stride = 3; needed > 0 && stride < nodes; stride += 2) {
    for (int i = stride; i < nodes && needed > 0; i += 2) {
      config.loops.emplace_back(i, i - stride);
      --needed;
    }
  }
  return testing::make_circle(config);
}

void Optimize(benchmark::State& state) {
  const int nodes = static_cast<int>(state.range(0));
  const int edges = static_cast<int>(state.range(1));
  const testing::Trajectory trajectory = make_trajectory(nodes, edges);
  const graph::Capacity capacity{std::max(nodes, 2), std::max(edges, 1)};
  graph::PoseGraph initial;
  if (!testing::build_graph(trajectory, false, initial, capacity) ||
      initial.edge_count() != edges) {
    state.SkipWithError("could not build the graph");
    return;
  }
  graph::PoseGraph working;
  (void)working.configure(capacity);
  int iterations = 0;
  double before_m = testing::rms_position_error_m(initial, trajectory);
  double after_m = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    working.copy_from(initial);
    state.ResumeTiming();
    const graph::OptimizeSummary summary = working.optimize(20);
    benchmark::DoNotOptimize(summary.final_cost);
    if (!summary.ok) state.SkipWithError("optimisation failed");
    iterations = summary.iterations;
  }
  after_m = testing::rms_position_error_m(working, trajectory);
  state.counters["lm_iterations"] = iterations;
  state.counters["rms_before_m"] = before_m;
  state.counters["rms_after_m"] = after_m;
}
BENCHMARK(Optimize)->Args({200, 400})->Args({256, 2048})->Unit(benchmark::kMillisecond);

void CopyFullGraph(benchmark::State& state) {
  const testing::Trajectory trajectory = make_trajectory(256, 2048);
  graph::PoseGraph source;
  graph::PoseGraph snapshot;
  if (!testing::build_graph(trajectory, false, source) ||
      !snapshot.configure(graph::Capacity{}).empty()) {
    state.SkipWithError("could not build the graph");
    return;
  }
  for (auto _ : state) {
    benchmark::DoNotOptimize(snapshot.copy_from(source));
  }
}
BENCHMARK(CopyFullGraph)->Unit(benchmark::kMicrosecond);

void RemoveNode(benchmark::State& state) {
  const testing::Trajectory trajectory = make_trajectory(256, 2048);
  graph::PoseGraph source;
  graph::PoseGraph working;
  if (!testing::build_graph(trajectory, false, source) ||
      !working.configure(graph::Capacity{}).empty()) {
    state.SkipWithError("could not build the graph");
    return;
  }
  for (auto _ : state) {
    state.PauseTiming();
    working.copy_from(source);
    state.ResumeTiming();
    benchmark::DoNotOptimize(working.remove_node(128));
  }
}
BENCHMARK(RemoveNode)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
