#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "rankslam/geometry/frontend.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "synthetic_scene.hpp"

namespace rankslam::geometry {
namespace {

double angle_deg(const Eigen::Isometry3d& T) {
  return Eigen::AngleAxisd(T.rotation()).angle() * 180.0 / M_PI;
}

class FrontendTest : public ::testing::Test {
 protected:
  void SetUp() override {
    camera_ = camera::DepthCameraModel(testing::test_calibration(), 5000.0);
    T_world_a_ = testing::look_at(Eigen::Vector3d(2.6, 2.4, 1.7), Eigen::Vector3d(0.9, 0.9, 0.3));
    // The second view: 4 cm to the side and 3° about a tilted axis, as between two frames.
    T_world_b_ = T_world_a_ * Eigen::Translation3d(0.04, -0.01, 0.015) *
                 Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d(0.2, 1.0, 0.1).normalized());
    depth_a_ = testing::render_depth(testing::room_corner(), testing::test_calibration(), T_world_a_, 1.4e-3, 1);
    depth_b_ = testing::render_depth(testing::room_corner(), testing::test_calibration(), T_world_b_, 1.4e-3, 2);
    ASSERT_EQ(frontend_.configure(camera_, config_), "");
    a_ = frontend_.make_features();
    b_ = frontend_.make_features();
  }

  camera::DepthCameraModel camera_;
  Eigen::Isometry3d T_world_a_;
  Eigen::Isometry3d T_world_b_;
  cv::Mat depth_a_;
  cv::Mat depth_b_;
  GeometryConfig config_;
  GeometricFrontend frontend_;
  GeometricFeatures a_;
  GeometricFeatures b_;
};

TEST_F(FrontendTest, ExtractFillsFeatures) {
  ASSERT_EQ(frontend_.extract(depth_a_, a_), GeometryStatus::kOk);
  EXPECT_GT(a_.count, 100);
  EXPECT_LE(a_.count, config_.max_keypoints);
  EXPECT_GT(a_.sampled_points, 2000);
  EXPECT_EQ(a_.cloud_count, a_.sampled_points);
  EXPECT_GT(a_.block_count, 10000);
  EXPECT_NEAR(a_.voxel_leaf_m, config_.voxel_leaf_factor * static_cast<double>(a_.resolution_m), 1e-6);
  for (int k = 0; k < a_.count; ++k) {
    const float z = a_.points_cam[static_cast<std::size_t>(k)].z();
    EXPECT_GT(z, 0.0F);
    EXPECT_GT(a_.sigma_m[static_cast<std::size_t>(k)], 0.0F);
    EXPECT_NEAR(a_.normals[static_cast<std::size_t>(k)].norm(), 1.0F, 1e-4F);
  }
}

TEST_F(FrontendTest, RegistersTwoViewsOfTheRoom) {
  ASSERT_EQ(frontend_.extract(depth_a_, a_), GeometryStatus::kOk);
  ASSERT_EQ(frontend_.extract(depth_b_, b_), GeometryStatus::kOk);
  const FrameRegistration r = frontend_.register_frames(a_, b_);
  ASSERT_TRUE(r.ok) << to_string(r.status);
  EXPECT_TRUE(r.msse_ok);
  EXPECT_GT(r.matches, 30);
  EXPECT_GE(r.inliers, config_.min_inliers);
  const Eigen::Isometry3d truth = T_world_a_.inverse() * T_world_b_;
  const Eigen::Isometry3d error = truth.inverse() * r.T_previous_current;
  EXPECT_LT(error.translation().norm(), 0.003);
  EXPECT_LT(angle_deg(error), 0.1);
}

// With a thread team the front-end computes the same cloud, keypoints, descriptors, matches and
// motion as on one thread, for every detector.
TEST_F(FrontendTest, AThreadTeamGivesTheSameFeaturesAndMotion) {
  parallel::ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  for (const KeypointMethod method : {KeypointMethod::kIs3d, KeypointMethod::kRos, KeypointMethod::kUniform}) {
    SCOPED_TRACE(to_string(method));
    GeometryConfig config = config_;
    config.keypoint_method = method;
    GeometricFrontend serial;
    GeometricFrontend shared;
    ASSERT_EQ(serial.configure(camera_, config), "");
    ASSERT_EQ(shared.configure(camera_, config, {}, &team), "");
    GeometricFeatures serial_a = serial.make_features();
    GeometricFeatures serial_b = serial.make_features();
    GeometricFeatures shared_a = shared.make_features();
    GeometricFeatures shared_b = shared.make_features();
    ASSERT_EQ(serial.extract(depth_a_, serial_a), GeometryStatus::kOk);
    ASSERT_EQ(serial.extract(depth_b_, serial_b), GeometryStatus::kOk);
    ASSERT_EQ(shared.extract(depth_a_, shared_a), GeometryStatus::kOk);
    ASSERT_EQ(shared.extract(depth_b_, shared_b), GeometryStatus::kOk);
    for (const auto* pair : {&serial_a, &serial_b}) {
      const GeometricFeatures& one = *pair;
      const GeometricFeatures& two = pair == &serial_a ? shared_a : shared_b;
      ASSERT_EQ(one.cloud_count, two.cloud_count);
      ASSERT_EQ(one.count, two.count);
      for (int i = 0; i < one.cloud_count; ++i) {
        const auto k = static_cast<std::size_t>(i);
        ASSERT_EQ(one.cloud_points[k], two.cloud_points[k]) << "point " << i;
        ASSERT_EQ(one.cloud_normals[k], two.cloud_normals[k]) << "normal " << i;
      }
      for (int i = 0; i < one.count; ++i) ASSERT_EQ(one.points_cam[static_cast<std::size_t>(i)], two.points_cam[static_cast<std::size_t>(i)]);
      const auto size = static_cast<std::size_t>(one.count) * kShotSize;
      EXPECT_TRUE(std::equal(one.descriptors.begin(), one.descriptors.begin() + static_cast<std::ptrdiff_t>(size),
                             two.descriptors.begin()));
    }
    const FrameRegistration r1 = serial.register_frames(serial_a, serial_b);
    const FrameRegistration r2 = shared.register_frames(shared_a, shared_b);
    ASSERT_TRUE(r1.ok);
    EXPECT_EQ(r1.matches, r2.matches);
    EXPECT_EQ(r1.inliers, r2.inliers);
    EXPECT_TRUE(r1.T_previous_current.matrix() == r2.T_previous_current.matrix());
  }
}

TEST_F(FrontendTest, DescriptorsBringLargeMotionsIntoIcpsReach) {
  // 12 cm and 8° between the views: the MSSE estimate from the SHOT matches alone is coarse (the
  // keypoints are voxel centroids), and ICP started only from it recovers the motion.
  const Eigen::Isometry3d T_world_c =
      T_world_a_ * Eigen::Translation3d(0.12, -0.03, 0.04) *
      Eigen::AngleAxisd(8.0 * M_PI / 180.0, Eigen::Vector3d(0.2, 1.0, 0.1).normalized());
  const cv::Mat depth_c = testing::render_depth(testing::room_corner(), testing::test_calibration(), T_world_c, 1.4e-3, 3);
  const Eigen::Isometry3d truth = T_world_a_.inverse() * T_world_c;
  for (const int icp_iterations : {0, 8}) {
    config_.icp_iterations = icp_iterations;
    config_.icp_guess_fallback = 0;
    ASSERT_EQ(frontend_.configure(camera_, config_), "");
    ASSERT_EQ(frontend_.extract(depth_a_, a_), GeometryStatus::kOk);
    ASSERT_EQ(frontend_.extract(depth_c, b_), GeometryStatus::kOk);
    const FrameRegistration r = frontend_.register_frames(a_, b_);
    ASSERT_TRUE(r.ok) << to_string(r.status);
    ASSERT_TRUE(r.msse_ok);
    const Eigen::Isometry3d error = truth.inverse() * r.T_previous_current;
    if (icp_iterations == 0) {
      EXPECT_EQ(r.refined_from, RefinementStart::kNone);
      EXPECT_LT(error.translation().norm(), 0.08);
      EXPECT_LT(angle_deg(error), 2.0);
    } else {
      EXPECT_EQ(r.refined_from, RefinementStart::kMsse);
      EXPECT_LT(error.translation().norm(), 0.005);
      EXPECT_LT(angle_deg(error), 0.15);
    }
  }
}

TEST_F(FrontendTest, SelfRegistrationIsIdentity) {
  ASSERT_EQ(frontend_.extract(depth_a_, a_), GeometryStatus::kOk);
  const FrameRegistration r = frontend_.register_frames(a_, a_);
  ASSERT_TRUE(r.ok);
  // The fine stage fits the dense block means to the centroids' planes: identity up to noise.
  EXPECT_LT(r.T_previous_current.translation().norm(), 1e-3);
  EXPECT_LT(angle_deg(r.T_previous_current), 0.05);
  EXPECT_EQ(r.matches, a_.count);  // every descriptor is its own mutual nearest neighbour
}

TEST_F(FrontendTest, CorrespondencesPairMatchedKeypoints) {
  ASSERT_EQ(frontend_.extract(depth_a_, a_), GeometryStatus::kOk);
  ASSERT_EQ(frontend_.extract(depth_b_, b_), GeometryStatus::kOk);
  GeometricCorrespondences c = frontend_.make_correspondences();
  ASSERT_EQ(frontend_.correspondences(a_, b_, c), GeometryStatus::kOk);
  ASSERT_GT(c.count, 10);
  for (int i = 0; i < c.count; ++i) {
    const DescriptorMatch& m = c.matches[static_cast<std::size_t>(i)];
    EXPECT_EQ(c.previous.col(i), a_.points_cam[static_cast<std::size_t>(m.a)].cast<double>());
    EXPECT_EQ(c.current.col(i), b_.points_cam[static_cast<std::size_t>(m.b)].cast<double>());
    const double expected = std::hypot(a_.sigma_m[static_cast<std::size_t>(m.a)], b_.sigma_m[static_cast<std::size_t>(m.b)]);
    EXPECT_NEAR(c.sigma_m[static_cast<std::size_t>(i)], expected, 1e-9);
  }
}

TEST_F(FrontendTest, FailuresAreStatusesNotCrashes) {
  EXPECT_EQ(frontend_.extract(cv::Mat(), a_), GeometryStatus::kInvalidImage);
  EXPECT_EQ(a_.count, 0);
  EXPECT_EQ(frontend_.extract(cv::Mat(480, 640, CV_16UC1, cv::Scalar(0)), a_), GeometryStatus::kTooFewPoints);
  GeometricFeatures tiny;
  EXPECT_EQ(frontend_.extract(depth_a_, tiny), GeometryStatus::kCapacityExceeded);
  const FrameRegistration r = frontend_.register_frames(a_, a_);
  EXPECT_FALSE(r.ok);
  GeometricFrontend unconfigured;
  EXPECT_EQ(unconfigured.extract(depth_a_, a_), GeometryStatus::kNotConfigured);
  EXPECT_FALSE(unconfigured.register_frames(a_, a_).ok);
}

TEST_F(FrontendTest, ConfigureNamesBadSettings) {
  GeometryConfig bad;
  bad.shot_radius_m = 0.0;
  GeometricFrontend frontend;
  EXPECT_NE(frontend.configure(camera_, bad).find("shot_radius_m"), std::string::npos);
  FrontendCapacities capacities;
  capacities.max_keypoints = 10;
  EXPECT_NE(frontend.configure(camera_, GeometryConfig{}, capacities).find("max_keypoints"), std::string::npos);
  EXPECT_FALSE(frontend.configured());
  // A sensor so noisy that the ICP's pass-through margin (5 σ at 4 m) leaves it no depth.
  GeometryConfig margin;
  margin.icp_pass_through_margin_sigmas = 5.0;
  const camera::DepthCameraModel noisy(testing::test_calibration(), 5000.0, 0.05);
  EXPECT_NE(frontend.configure(noisy, margin).find("icp_pass_through_margin_sigmas"), std::string::npos);
  EXPECT_EQ(frontend.configure(camera_, margin), "");  // the Kinect's noise leaves 3.5 m
}

}  // namespace
}  // namespace rankslam::geometry
