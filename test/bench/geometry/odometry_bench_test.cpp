// Depth-only frame-to-frame odometry with the geometric front-end, through the API directly
// (ReplayDepthCamera → GeometricFrontend::extract / register_frames → G_n = G_{n−1}·T), scored
// with the TUM ATE against the recordings' ground truth.

#include <cstdio>

#include <gtest/gtest.h>

#include "geometry_bench_support.hpp"

namespace rankslam::geometry::bench {
namespace {

void print(const char* name, const OdometryResult& r) {
  std::printf("%s: %d frames, %d failed registrations, %.0f sampled points, %.0f keypoints, "
              "%.0f matches, %.0f MSSE inliers, ATE %.4f m, RPE %.4f m/s %.3f deg/s\n",
              name, r.frames, r.failed_registrations, r.mean_sampled_points, r.mean_keypoints,
              r.mean_matches, r.mean_inliers, r.ate_rmse_m, r.rpe_translation_m_per_s,
              r.rpe_rotation_deg_per_s);
}

TEST(GeometricOdometry, ZigzagPlainWithin2cm) {
  std::filesystem::path root;
  ASSERT_EQ(simulated_recording("zigzag-plain", 0, 1, root), "");
  OdometryResult result;
  ASSERT_EQ(run_geometric_odometry(root, GeometryConfig{}, result), "");
  print("zigzag-plain", result);
  EXPECT_EQ(result.failed_extractions, 0);
  EXPECT_EQ(result.failed_registrations, 0);
  EXPECT_GE(result.ate_rmse_m, 0.0);
  EXPECT_LE(result.ate_rmse_m, 0.02);
}

TEST(GeometricOdometry, ZigzagPlainWithoutIcpReported) {
  // The thesis' registration alone (descriptor matches + MSSE, no ICP), for comparison.
  std::filesystem::path root;
  ASSERT_EQ(simulated_recording("zigzag-plain", 0, 1, root), "");
  GeometryConfig config;
  config.icp_iterations = 0;
  OdometryResult result;
  ASSERT_EQ(run_geometric_odometry(root, config, result), "");
  print("zigzag-plain, MSSE only", result);
  EXPECT_GE(result.ate_rmse_m, 0.0);
}

TEST(GeometricOdometry, Fr1RpyHeadReported) {
  const auto root = shared_recording("fr1_rpy_head");
  if (root.empty()) GTEST_SKIP() << "shared data RANKSLAM_SHARED_DATA/tum/fr1_rpy_head is absent";
  OdometryResult result;
  ASSERT_EQ(run_geometric_odometry(root, GeometryConfig{}, result), "");
  print("fr1_rpy_head", result);
  EXPECT_EQ(result.failed_extractions, 0);
  // A regression bound, not a target: 0.12 m was measured (peers on this data: OpenCV
  // ICPOdometry 0.081 m, RgbdOdometry 0.050 m, with colour).
  EXPECT_LE(result.ate_rmse_m, 0.2);
}

}  // namespace
}  // namespace rankslam::geometry::bench
