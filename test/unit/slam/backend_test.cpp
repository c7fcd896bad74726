// The pose-graph back-end on its own: a drifted chain of key-frames closed by a loop closure is
// pulled back by a solve, the store's key-frames take the optimised poses, the correction of the
// newest key-frame is what the tracking takes, and frames re-express on their key-frames.
#include "rankslam/slam/backend.hpp"

#include "rankslam/core/lie.hpp"

#include <gtest/gtest.h>

namespace rankslam::slam {
namespace {

Eigen::Isometry3d along_x(double x_m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x_m, 0.0, 0.0);
  return T;
}

class BackendTest : public ::testing::Test {
 protected:
  BackendTest() { backend_.set_synchronous(true); }

  // A key-frame at `T_world_cam` in the next free slot; its node joins the graph.
  int add_keyframe(const Eigen::Isometry3d& T_world_cam) {
    const int slot = store_.free_slot();
    store_.occupy(slot);
    StoredKeyframe& keyframe = store_.slot(slot);
    keyframe.sequence = ++sequence_;
    keyframe.T_world_cam = T_world_cam;
    keyframe.node = backend_.add_node(T_world_cam, keyframe.generation);
    return slot;
  }

  SlamConfig config_;
  KeyframeStore store_{8, 0, 0, 0, 0};
  Backend backend_{config_, Eigen::Isometry3d::Identity(), false};
  std::int64_t sequence_ = 0;
};

TEST_F(BackendTest, ALoopClosurePullsADriftedChainBackAndMovesTheStore) {
  // Truth: key-frames 1 m apart along x. Tracking drifted by 10 % per step; the chain's edges
  // carry that drift weakly, the closure from the first to the last the truth strongly.
  constexpr int kKeyframes = 4;
  int slots[kKeyframes];
  for (int i = 0; i < kKeyframes; ++i) slots[i] = add_keyframe(along_x(1.1 * i));
  for (int i = 1; i < kKeyframes; ++i) {
    backend_.add_sequential_edges(store_.slot(slots[i - 1]).node, store_.slot(slots[i]).node, along_x(1.1),
                                  backend_.registration_information(20, 1.0));
  }
  Eigen::Isometry3d correction;
  backend_.submit_pending();
  EXPECT_FALSE(backend_.take_solve(store_, correction)) << "nothing to solve before a closure";

  graph::Edge closure;
  closure.from = store_.slot(slots[0]).node;
  closure.to = store_.slot(slots[kKeyframes - 1]).node;
  closure.T_from_to = along_x(3.0);
  closure.information = backend_.registration_information(2000, 1.0);
  closure.kind = graph::EdgeKind::kLoopClosure;
  ASSERT_TRUE(backend_.add_loop_closure(closure));
  const Eigen::Isometry3d before = store_.slot(slots[kKeyframes - 1]).T_world_cam;
  backend_.submit_pending();
  ASSERT_TRUE(backend_.take_solve(store_, correction));

  const Eigen::Isometry3d& after = store_.slot(slots[kKeyframes - 1]).T_world_cam;
  EXPECT_NEAR(after.translation().x(), 3.0, 0.01);
  EXPECT_NEAR(store_.slot(slots[0]).T_world_cam.translation().x(), 0.0, 0.01);
  // The tracking's correction is the newest key-frame's move.
  EXPECT_LT(((correction * before).matrix() - after.matrix()).cwiseAbs().maxCoeff(), 1e-9);

  // A frame half a metre past the last key-frame re-expressed on its optimised pose.
  const StoredKeyframe& last = store_.slot(slots[kKeyframes - 1]);
  Eigen::Isometry3d T_world_frame;
  ASSERT_TRUE(backend_.optimized_pose(last.node, last.generation, along_x(0.5), T_world_frame));
  EXPECT_NEAR(T_world_frame.translation().x(), after.translation().x() + 0.5, 1e-9);
  // A retired key-frame's frames keep their pose.
  backend_.remove_node(last.node);
  EXPECT_FALSE(backend_.optimized_pose(last.node, last.generation, along_x(0.5), T_world_frame));
}

TEST_F(BackendTest, AGraphWhoseEdgesAgreeStaysWhereItIs) {
  const int a = add_keyframe(Eigen::Isometry3d::Identity());
  backend_.restart_wheel_motion();
  nav::MotionPrior prior;
  prior.T_previous_current = along_x(0.1);
  prior.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 1e-6;
  for (int i = 0; i < 5; ++i) backend_.accumulate_wheel_motion(&prior);
  const int b = add_keyframe(along_x(0.5));
  // The sequential, wheel and closure edges all agree with the key-frames: a solve keeps them.
  backend_.add_sequential_edges(store_.slot(a).node, store_.slot(b).node, along_x(0.5),
                                backend_.registration_information(50, 1.0));
  backend_.restart_wheel_motion();
  backend_.accumulate_wheel_motion(&prior);
  backend_.accumulate_wheel_motion(nullptr);  // a frame without wheels: no wheel edge this time
  const int c = add_keyframe(along_x(0.7));
  backend_.add_sequential_edges(store_.slot(b).node, store_.slot(c).node, along_x(0.2),
                                backend_.registration_information(50, 1.0));
  graph::Edge closure;
  closure.from = store_.slot(a).node;
  closure.to = store_.slot(c).node;
  closure.T_from_to = along_x(0.7);
  closure.information = backend_.registration_information(50, 1.0);
  closure.kind = graph::EdgeKind::kLoopClosure;
  ASSERT_TRUE(backend_.add_loop_closure(closure));
  backend_.submit_pending();
  Eigen::Isometry3d correction;
  ASSERT_TRUE(backend_.take_solve(store_, correction));
  EXPECT_NEAR(store_.slot(b).T_world_cam.translation().x(), 0.5, 1e-6);
  EXPECT_NEAR(store_.slot(c).T_world_cam.translation().x(), 0.7, 1e-6);
  EXPECT_LT((correction.matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-6);
}

// Local mapping's refinement replaces a registration edge's measurement and queues a solve, but
// not for nodes that left the graph since, nor between two held (loaded-map) key-frames.
TEST_F(BackendTest, ARefinedRegistrationEdgeMovesTheChainUnlessItsNodesChangedOrAreHeld) {
  const int a = add_keyframe(along_x(0.0));
  const int b = add_keyframe(along_x(1.1));
  const StoredKeyframe& first = store_.slot(a);
  const StoredKeyframe& second = store_.slot(b);
  backend_.add_sequential_edges(first.node, second.node, along_x(1.1), backend_.registration_information(20, 1.0));
  EXPECT_FALSE(backend_.refine_sequential_edge(first.node, first.generation + 1, second.node, second.generation,
                                               along_x(1.0)));
  ASSERT_TRUE(backend_.refine_sequential_edge(first.node, first.generation, second.node, second.generation,
                                              along_x(1.0)));
  backend_.submit_pending();
  Eigen::Isometry3d correction;
  ASSERT_TRUE(backend_.take_solve(store_, correction));
  EXPECT_NEAR(store_.slot(b).T_world_cam.translation().x(), 1.0, 1e-6);
  EXPECT_NEAR(correction.translation().x(), -0.1, 1e-6);

  (void)backend_.graph_to_restore().hold(first.node);
  (void)backend_.graph_to_restore().hold(second.node);
  EXPECT_FALSE(backend_.refine_sequential_edge(first.node, first.generation, second.node, second.generation,
                                               along_x(0.5)));
}

}  // namespace
}  // namespace rankslam::slam
