#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/geometry/cloud.hpp"
#include "rankslam/geometry/keypoints.hpp"
#include "rankslam/geometry/shot.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "synthetic_scene.hpp"

namespace rankslam::geometry {
namespace {

class ShotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const camera::DepthCameraModel camera(testing::test_calibration(), 5000.0);
    const cv::Mat depth = testing::render_depth(
        testing::room_corner(), testing::test_calibration(),
        testing::look_at(Eigen::Vector3d(2.6, 2.4, 1.7), Eigen::Vector3d(0.9, 0.9, 0.3)), 1.0e-3);
    CloudPreprocessor preprocessor;
    ASSERT_EQ(preprocessor.configure(camera, config_, 16384), "");
    cloud_ = preprocessor.make_cloud();
    ASSERT_EQ(preprocessor.process(depth, cloud_), GeometryStatus::kOk);
    KeypointDetector detector;
    ASSERT_EQ(detector.configure(config_, 16384), "");
    keypoints_.resize(static_cast<std::size_t>(config_.max_keypoints));
    GeometryStatus status = GeometryStatus::kNotConfigured;
    keypoints_.resize(static_cast<std::size_t>(detector.detect(KeypointMethod::kIs3d, cloud_, keypoints_, status)));
    ASSERT_GT(keypoints_.size(), 50U);
    points_.assign(cloud_.points.begin(), cloud_.points.begin() + cloud_.size);
    normals_.assign(cloud_.normals.begin(), cloud_.normals.begin() + cloud_.size);
  }

  // Descriptors of the keypoints over the given support; rows of kShotSize, NaN-free; results.
  std::vector<float> describe(const std::vector<Eigen::Vector3f>& points,
                              const std::vector<Eigen::Vector3f>& normals,
                              std::vector<ShotResult>& results, bool best_kernel = true) const {
    PointGrid grid(static_cast<int>(points.size()));
    EXPECT_TRUE(grid.build(points, static_cast<float>(config_.shot_radius_m)));
    ShotEstimator shot(static_cast<int>(points.size()));
    shot.use_best_kernel(best_kernel);
    std::vector<float> out(keypoints_.size() * kShotSize);
    results.clear();
    for (std::size_t k = 0; k < keypoints_.size(); ++k) {
      results.push_back(shot.compute(points[static_cast<std::size_t>(keypoints_[k])], points, normals, grid,
                                     static_cast<float>(config_.shot_radius_m), config_.shot_min_neighbours,
                                     out.data() + k * kShotSize));
    }
    return out;
  }

  GeometryConfig config_;
  SampledCloud cloud_;
  std::vector<int> keypoints_;
  std::vector<Eigen::Vector3f> points_;
  std::vector<Eigen::Vector3f> normals_;
};

TEST_F(ShotTest, DescriptorsAreUnitNonNegativeHistograms) {
  std::vector<ShotResult> results;
  const std::vector<float> d = describe(points_, normals_, results);
  for (std::size_t k = 0; k < keypoints_.size(); ++k) {
    ASSERT_EQ(results[k], ShotResult::kOk);
    double norm = 0.0;
    for (int j = 0; j < kShotSize; ++j) {
      const float v = d[k * kShotSize + static_cast<std::size_t>(j)];
      EXPECT_GE(v, -1e-6F);
      norm += static_cast<double>(v) * static_cast<double>(v);
    }
    EXPECT_NEAR(norm, 1.0, 1e-5);
  }
}

TEST_F(ShotTest, InvariantToRigidMotion) {
  // The local reference frame makes the descriptor independent of the cloud's pose.
  const Eigen::Isometry3f T =
      Eigen::Translation3f(0.3F, -0.2F, 0.5F) *
      Eigen::AngleAxisf(0.7F, Eigen::Vector3f(0.3F, -1.0F, 0.4F).normalized());
  std::vector<Eigen::Vector3f> moved_points;
  std::vector<Eigen::Vector3f> moved_normals;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    moved_points.push_back(T * points_[i]);
    moved_normals.push_back(T.linear() * normals_[i]);
  }
  std::vector<ShotResult> results_a;
  std::vector<ShotResult> results_b;
  const std::vector<float> a = describe(points_, normals_, results_a);
  const std::vector<float> b = describe(moved_points, moved_normals, results_b);
  std::vector<double> similarity;
  for (std::size_t k = 0; k < keypoints_.size(); ++k) {
    double dot = 0.0;
    for (int j = 0; j < kShotSize; ++j) {
      dot += static_cast<double>(a[k * kShotSize + static_cast<std::size_t>(j)]) *
             static_cast<double>(b[k * kShotSize + static_cast<std::size_t>(j)]);
    }
    similarity.push_back(dot);
  }
  std::sort(similarity.begin(), similarity.end());
  EXPECT_GT(similarity[similarity.size() / 2], 0.9999);
  // A sign tie in the frame can flip a few; the rest must agree.
  EXPECT_GT(similarity[similarity.size() / 20], 0.99);
}

TEST_F(ShotTest, TooFewNeighboursIsReported) {
  const std::vector<Eigen::Vector3f> few = {Eigen::Vector3f(0, 0, 1), Eigen::Vector3f(0.01F, 0, 1),
                                            Eigen::Vector3f(0, 0.01F, 1)};
  const std::vector<Eigen::Vector3f> up(3, Eigen::Vector3f(0, 0, -1));
  PointGrid grid(3);
  ASSERT_TRUE(grid.build(few, 0.1F));
  ShotEstimator shot(3);
  std::vector<float> d(kShotSize);
  EXPECT_EQ(shot.compute(few[0], few, up, grid, 0.1F, 5, d.data()), ShotResult::kTooFewNeighbours);
}

// The vector kernel of the per-neighbour geometry (where the CPU has one) against the portable
// loop: the same bins and weights, so the same descriptors.
TEST_F(ShotTest, PortableAndVectorKernelsAgree) {
  if (!ShotEstimator::has_vector_kernel()) GTEST_SKIP() << "no vector target: only the portable loop runs here";
  std::vector<ShotResult> best_results;
  std::vector<ShotResult> portable_results;
  const std::vector<float> best = describe(points_, normals_, best_results, true);
  const std::vector<float> portable = describe(points_, normals_, portable_results, false);
  ASSERT_EQ(best_results, portable_results);
  ASSERT_EQ(best.size(), portable.size());
  std::size_t differing = 0;
  for (std::size_t k = 0; k < best.size(); ++k) differing += best[k] != portable[k] ? 1 : 0;
  EXPECT_EQ(differing, 0U) << "of " << best.size() << " descriptor values";
}

}  // namespace
}  // namespace rankslam::geometry
