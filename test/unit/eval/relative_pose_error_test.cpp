#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/eval/metrics.hpp"
#include "test_support.hpp"

namespace rankslam::eval {
namespace {

using test::helix;

// A measured relative pose between two stamps of a helix (a loop closure between a stored
// key-frame and a new one), exact or perturbed by a known error.
StampedRelativePose measured_between(const Trajectory& truth, std::size_t from, std::size_t to,
                                     const Eigen::Isometry3d& error = Eigen::Isometry3d::Identity()) {
  return {truth[from].stamp_s, truth[to].stamp_s,
          truth[from].T_world_cam.inverse() * truth[to].T_world_cam * error};
}

TEST(RelativePoseError, IsTheErrorBetweenTheMeasuredAndTheTrueMotion) {
  const Trajectory truth = helix(100.0, 20.0, 30.0);
  Eigen::Isometry3d off = Eigen::Isometry3d::Identity();
  off.translation() = Eigen::Vector3d(0.03, -0.04, 0.0);  // 5 cm
  off.linear() = Eigen::AngleAxisd(2.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const std::vector<StampedRelativePose> measured = {measured_between(truth, 10, 500),
                                                     measured_between(truth, 40, 580, off)};
  const auto errors = compute_relative_pose_errors(truth, measured);
  ASSERT_TRUE(errors.ok()) << errors.error();
  ASSERT_EQ(errors.value().size(), 2U);
  const RelativePoseError& exact = errors.value()[0];
  EXPECT_TRUE(exact.has_ground_truth);
  EXPECT_LT(exact.translation_m, 1e-9);
  EXPECT_LT(exact.rotation_deg, 1e-6);
  EXPECT_DOUBLE_EQ(exact.stamp_gt_from_s, truth[10].stamp_s);
  EXPECT_DOUBLE_EQ(exact.stamp_gt_to_s, truth[500].stamp_s);
  const RelativePoseError& perturbed = errors.value()[1];
  EXPECT_TRUE(perturbed.has_ground_truth);
  EXPECT_NEAR(perturbed.translation_m, 0.05, 1e-9);
  EXPECT_NEAR(perturbed.rotation_deg, 2.0, 1e-6);
}

TEST(RelativePoseError, AStampFarFromTheGroundTruthLeavesItsMeasurementUnchecked) {
  const Trajectory truth = helix(100.0, 20.0, 30.0);  // 30 Hz for 20 s from t = 100 s
  StampedRelativePose after_the_end = measured_between(truth, 10, 500);
  after_the_end.stamp_to_s = truth.back().stamp_s + 1.0;
  const std::vector<StampedRelativePose> measured = {after_the_end, measured_between(truth, 20, 30)};
  const auto errors = compute_relative_pose_errors(truth, measured);
  ASSERT_TRUE(errors.ok()) << errors.error();
  EXPECT_FALSE(errors.value()[0].has_ground_truth);
  EXPECT_TRUE(errors.value()[1].has_ground_truth);
  // With an explicit gap wide enough, the end pose stands in.
  const auto widened = compute_relative_pose_errors(truth, measured, 2.0);
  ASSERT_TRUE(widened.ok());
  EXPECT_TRUE(widened.value()[0].has_ground_truth);
  EXPECT_DOUBLE_EQ(widened.value()[0].stamp_gt_to_s, truth.back().stamp_s);
}

TEST(RelativePoseError, FailsWithoutAUsableGroundTruth) {
  const Trajectory truth = helix(100.0, 20.0, 30.0);
  const std::vector<StampedRelativePose> measured = {measured_between(truth, 0, 1)};
  const Trajectory one_pose(truth.begin(), truth.begin() + 1);
  const auto too_short = compute_relative_pose_errors(one_pose, measured);
  ASSERT_FALSE(too_short.ok());
  EXPECT_NE(too_short.error().find("fewer than 2"), std::string::npos) << too_short.error();
  EXPECT_FALSE(compute_relative_pose_errors(truth, measured, -1.0).ok());
  Trajectory broken = truth;
  broken[3].T_world_cam.translation().x() = std::nan("");
  const auto not_finite = compute_relative_pose_errors(broken, measured);
  ASSERT_FALSE(not_finite.ok());
  EXPECT_NE(not_finite.error().find("ground truth pose 3"), std::string::npos) << not_finite.error();
}

}  // namespace
}  // namespace rankslam::eval
