// The dense refinement allocates nothing per frame: pyramids and point buffers are sized at
// set-up (the loop is fixed-memory).
#include "allocation_counter.hpp"
#include "rankslam/dense/aligner.hpp"

#include "rendered_plane.hpp"

#include <gtest/gtest.h>

namespace rankslam::dense {
namespace {

TEST(DenseAllocations, PrepareAndAlignAllocateNothingOnceReserved) {
  const camera::DepthCameraModel camera(test::plane_camera(), test::kDepthScale);
  DenseAligner aligner(camera, {});
  DenseFrame reference;
  DenseFrame current;
  aligner.reserve(reference);
  aligner.reserve(current);
  const Eigen::Isometry3d T_ref_cur = test::motion(2.0, {0.3, 1.0, 0.2}, {0.03, -0.02, 0.04});
  cv::Mat grey_a, depth_a, grey_b, depth_b;
  test::render_plane(test::plane_camera(), Eigen::Isometry3d::Identity(), true, grey_a, depth_a);
  test::render_plane(test::plane_camera(), T_ref_cur, true, grey_b, depth_b);
  const float metres = static_cast<float>(1.0 / test::kDepthScale);
  int refined = 0;
  {
    test_support::CountAllocations count;
    for (int frame = 0; frame < 3; ++frame) {
      ASSERT_TRUE(reference.prepare(grey_a, depth_a, metres, 0.3F, 4.0F, 0));
      ASSERT_TRUE(current.prepare(grey_b, depth_b, metres, 0.3F, 4.0F, 0));
      Eigen::Isometry3d T = test::motion(0.4, {1.0, 0.0, 0.0}, {0.01, 0.0, 0.0}) * T_ref_cur.inverse();
      refined += aligner.align(reference, current, T).ok ? 1 : 0;
    }
    EXPECT_EQ(count.allocations(), 0);
  }
  EXPECT_EQ(refined, 3);
}

}  // namespace
}  // namespace rankslam::dense
