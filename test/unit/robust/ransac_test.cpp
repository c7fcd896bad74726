// Fixed-threshold RANSAC over the rigid model.

#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/robust/ransac.hpp"
#include "rankslam/robust/rigid.hpp"
#include "synthetic_correspondences.hpp"

namespace rankslam::robust {
namespace {

constexpr int kPoints = 500;

testing::Scene scene_with(double outlier_fraction, std::uint64_t seed) {
  testing::SceneConfig config;
  config.points = kPoints;
  config.outlier_fraction = outlier_fraction;
  config.seed = seed;
  return testing::make_scene(config);
}

TEST(RansacRigid, RecoversTransformAndReportsThresholdInliers) {
  RigidModel model(kPoints);
  RobustWorkspace workspace(kPoints);
  RansacConfig config;
  config.inlier_threshold = 0.02;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    const testing::Scene scene = scene_with(0.5, seed);
    ASSERT_EQ(model.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
    const auto result = estimate_ransac(model, config, workspace);
    ASSERT_TRUE(result.ok());
    EXPECT_TRUE(result.refined);
    EXPECT_LT(translation_difference_m(result.model, scene.T_t_s), 0.004);
    EXPECT_LT(rotation_difference_rad(result.model, scene.T_t_s) * 180.0 / std::numbers::pi, 0.2);
    // Inliers are exactly the residuals within the threshold of the selected hypothesis.
    const double t2 = config.inlier_threshold * config.inlier_threshold;
    const auto k = static_cast<std::size_t>(result.inlier_count);
    ASSERT_LE(k, result.sorted_sq_residuals.size());
    for (std::size_t i = 0; i < result.sorted_sq_residuals.size(); ++i) {
      if (i < k) {
        EXPECT_LE(result.sorted_sq_residuals[i], t2);
      } else {
        EXPECT_GT(result.sorted_sq_residuals[i], t2);
      }
    }
    int true_inliers = 0;
    for (const int i : result.inliers) {
      true_inliers += scene.kind[static_cast<std::size_t>(i)] == testing::PointKind::kInlier;
    }
    EXPECT_GT(true_inliers, 0.95 * result.inlier_count);
    EXPECT_GT(result.scale, 0.0);
    EXPECT_LE(result.scale, config.inlier_threshold);
  }
}

TEST(RansacRigid, ReproducibleAndStatuses) {
  RigidModel model(kPoints);
  RobustWorkspace workspace(kPoints);
  const testing::Scene scene = scene_with(0.4, 9);
  ASSERT_EQ(model.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
  const auto a = estimate_ransac(model, RansacConfig{}, workspace);
  const Eigen::Matrix4d first = a.model.matrix();
  const auto b = estimate_ransac(model, RansacConfig{}, workspace);
  EXPECT_TRUE(b.model.matrix() == first);

  RansacConfig bad;
  bad.inlier_threshold = 0.0;
  EXPECT_EQ(estimate_ransac(model, bad, workspace).status, RobustStatus::kInvalidConfig);
  EXPECT_EQ(bad.validate(), "inlier_threshold");

  const Eigen::Matrix3Xd same = Eigen::Vector3d(0.0, 0.0, 1.0).replicate(1, 20);
  ASSERT_EQ(model.set_correspondences(same, same), RobustStatus::kOk);
  const auto degenerate = estimate_ransac(model, RansacConfig{}, workspace);
  EXPECT_EQ(degenerate.status, RobustStatus::kDegenerate);
  EXPECT_TRUE(degenerate.model.matrix().isIdentity(0.0));

  ASSERT_EQ(model.set_correspondences(scene.src.leftCols(2), scene.dst.leftCols(2)),
            RobustStatus::kOk);
  EXPECT_EQ(estimate_ransac(model, RansacConfig{}, workspace).status,
            RobustStatus::kTooFewPoints);
}

}  // namespace
}  // namespace rankslam::robust
