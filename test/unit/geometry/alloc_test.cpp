// Fixed memory in the per-frame loop: after set-up and one warm-up frame, extract() and
// register_frames() (cloud, keypoints, SHOT, matching, MSSE, ICP) allocate nothing. Counts global
// operator new/delete (replaced by the allocation-counter test library) and, outside sanitizer builds, malloc itself, because
// Eigen's heap temporaries bypass operator new.

#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"

#include "rankslam/geometry/frontend.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "synthetic_scene.hpp"

namespace rankslam::geometry {
namespace {

using test_support::CountAllocations;

TEST(GeometryAllocations, CounterSeesAllocations) {
  long new_calls = 0;
  long malloc_calls = 0;
  {
    CountAllocations count;
    auto* v = new std::vector<double>(100, 1.0);
    const Eigen::VectorXd x = Eigen::VectorXd::Ones(1000);
    volatile double sink = x.sum() + (*v)[3];
    (void)sink;
    delete v;
    new_calls = count.new_calls();
    malloc_calls = count.malloc_calls();
  }
  EXPECT_GE(new_calls, 2);
  if (test_support::counts_malloc()) {
    EXPECT_GE(malloc_calls, 3);
  }
}

TEST(GeometryAllocations, NoneInTheSteadyState) {
  const camera::DepthCameraModel camera(testing::test_calibration(), 5000.0);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 6; ++i) {
    const Eigen::Isometry3d T_world_cam =
        testing::look_at(Eigen::Vector3d(2.6 + 0.05 * i, 2.4 - 0.04 * i, 1.7), Eigen::Vector3d(0.9, 0.9, 0.3));
    frames.push_back(testing::render_depth(testing::room_corner(), testing::test_calibration(), T_world_cam, 1.4e-3,
                                           static_cast<std::uint32_t>(i + 1)));
  }
  // On one thread and on a team of two (whose workers are counted too).
  parallel::ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  for (const bool shared : {false, true})
  for (const KeypointMethod method : {KeypointMethod::kIs3d, KeypointMethod::kRos, KeypointMethod::kUniform}) {
    SCOPED_TRACE(shared ? "team of 2" : "one thread");
    GeometryConfig config;
    config.keypoint_method = method;
    GeometricFrontend frontend;
    ASSERT_EQ(frontend.configure(camera, config, {}, shared ? &team : nullptr), "");
    GeometricFeatures previous = frontend.make_features();
    GeometricFeatures current = frontend.make_features();
    GeometricCorrespondences correspondences = frontend.make_correspondences();
    // Warm-up: the first frames may touch lazily initialised state (none is expected).
    ASSERT_EQ(frontend.extract(frames[0], previous), GeometryStatus::kOk);
    ASSERT_EQ(frontend.extract(frames[1], current), GeometryStatus::kOk);
    ASSERT_TRUE(frontend.register_frames(previous, current).ok);

    long new_calls = 0;
    long malloc_calls = 0;
    int registered = 0;
    {
      CountAllocations count;
      for (std::size_t i = 2; i < frames.size(); ++i) {
        std::swap(previous, current);
        if (frontend.extract(frames[i], current) != GeometryStatus::kOk) continue;
        (void)frontend.correspondences(previous, current, correspondences);
        registered += frontend.register_frames(previous, current).ok ? 1 : 0;
      }
      new_calls = count.new_calls();
      malloc_calls = count.malloc_calls();
    }
    EXPECT_EQ(registered, 4) << to_string(method);
    EXPECT_EQ(new_calls, 0) << to_string(method);
    EXPECT_EQ(malloc_calls, 0) << to_string(method);
  }
}

}  // namespace
}  // namespace rankslam::geometry
