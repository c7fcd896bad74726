// KITTI segment errors on trajectories whose errors can be worked out by hand.
#include "rankslam/eval/kitti.hpp"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace {

using rankslam::eval::Trajectory;

/// 300 poses 1 m apart along x, one per second.
Trajectory straight_line(double scale, double yaw_per_frame_rad) {
  Trajectory trajectory;
  for (int i = 0; i < 300; ++i) {
    rankslam::eval::StampedPose pose;
    pose.stamp_s = i;
    pose.T_world_cam.translation() = Eigen::Vector3d(scale * i, 0.0, 0.0);
    pose.T_world_cam.linear() = Eigen::AngleAxisd(yaw_per_frame_rad * i, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    trajectory.push_back(pose);
  }
  return trajectory;
}

TEST(SegmentErrors, ScaleErrorGivesItsPercentage) {
  rankslam::eval::SegmentOptions options;
  options.lengths_m = {100.0, 200.0};
  const auto result = rankslam::eval::compute_segment_errors(straight_line(1.0, 0.0), straight_line(1.01, 0.0), options);
  ASSERT_TRUE(result.ok()) << result.error();
  // A segment ends at the first pose beyond L: 101 m (201 m) of ground truth, 1 % of it wrong.
  // L = 100: first frames 0, 10, …, 190 (20 segments); L = 200: 0, …, 90 (10 segments).
  ASSERT_EQ(result.value().per_length.size(), 2u);
  EXPECT_EQ(result.value().per_length[0].segments, 20);
  EXPECT_EQ(result.value().per_length[1].segments, 10);
  EXPECT_NEAR(result.value().per_length[0].translation_percent, 1.01, 1e-9);
  EXPECT_NEAR(result.value().per_length[1].translation_percent, 1.005, 1e-9);
  EXPECT_NEAR(result.value().translation_percent, (20 * 1.01 + 10 * 1.005) / 30.0, 1e-9);
  EXPECT_NEAR(result.value().rotation_deg_per_m, 0.0, 1e-9);
  EXPECT_NEAR(result.value().path_length_m, 299.0, 1e-9);
}

TEST(SegmentErrors, HeadingDriftGivesDegreesPerMetre) {
  rankslam::eval::SegmentOptions options;
  options.lengths_m = {100.0};
  constexpr double kYaw = 1e-4;
  const auto result = rankslam::eval::compute_segment_errors(straight_line(1.0, 0.0), straight_line(1.0, kYaw), options);
  ASSERT_TRUE(result.ok()) << result.error();
  EXPECT_NEAR(result.value().rotation_deg_per_m, kYaw * 101.0 / 100.0 * 180.0 / std::numbers::pi, 1e-9);
}

TEST(SegmentErrors, ShortRunHasNoSegment) {
  Trajectory trajectory = straight_line(1.0, 0.0);
  trajectory.resize(50);
  const auto result = rankslam::eval::compute_segment_errors(trajectory, trajectory);
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.error().find("shorter than the shortest segment (100 m)"), std::string::npos) << result.error();
}

}  // namespace
