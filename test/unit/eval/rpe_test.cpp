#include <cmath>
#include <filesystem>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/eval/metrics.hpp"
#include "test_support.hpp"

namespace rankslam::eval {
namespace {

using test::helix;
using test::make_pose;

// Dyadic periods: stamps, and stamp + 1 s, are exact, so every pair spans exactly delta.
constexpr double kTruthPeriod_s = 1.0 / 64.0;
constexpr double kEstimatePeriod_s = 1.0 / 16.0;

Trajectory straight_line(double speed_m_per_s, double duration_s, double period_s) {
  Trajectory trajectory;
  for (int k = 0; k * period_s <= duration_s; ++k) {
    const double t = 1000.0 + k * period_s;
    trajectory.push_back(
        {t, make_pose({speed_m_per_s * (t - 1000.0), 0.0, 0.0}, Eigen::Quaterniond::Identity())});
  }
  return trajectory;
}

Trajectory turning_on_the_spot(double rate_deg_per_s, double duration_s, double period_s) {
  Trajectory trajectory;
  for (int k = 0; k * period_s <= duration_s; ++k) {
    const double t = 1000.0 + k * period_s;
    const double angle_rad = rate_deg_per_s * (t - 1000.0) * std::numbers::pi / 180.0;
    trajectory.push_back(
        {t, make_pose({1.0, 2.0, 0.5},
                      Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitZ())))});
  }
  return trajectory;
}

TEST(Rpe, IdenticalTrajectoriesHaveZeroDrift) {
  const Trajectory truth = helix(100.0, 20.0, 100.0);
  const Result<RpeResult> rpe = compute_rpe(truth, truth);
  ASSERT_TRUE(rpe.ok()) << rpe.error();
  EXPECT_GT(rpe.value().translation_m_per_s.count, 1800U);
  EXPECT_LT(rpe.value().translation_m_per_s.max, 1e-12);
  EXPECT_LT(rpe.value().rotation_deg_per_s.max, 1e-5);
}

TEST(Rpe, ConstantTranslationalDriftIsItsRate) {
  // Ground truth 0.5 m/s, the estimate believes 0.55 m/s: 0.05 m of drift every second.
  const Trajectory truth = straight_line(0.5, 30.0, kTruthPeriod_s);
  const Trajectory estimate = straight_line(0.55, 30.0, kEstimatePeriod_s);
  const Result<RpeResult> rpe = compute_rpe(truth, estimate);
  ASSERT_TRUE(rpe.ok()) << rpe.error();
  const RpeResult& result = rpe.value();
  EXPECT_NEAR(result.translation_m_per_s.rmse, 0.05, 1e-9);
  EXPECT_NEAR(result.translation_m_per_s.mean, 0.05, 1e-9);
  EXPECT_NEAR(result.translation_m_per_s.max, 0.05, 1e-9);
  EXPECT_LT(result.rotation_deg_per_s.max, 1e-9);
  for (const RpePair& pair : result.pairs) {
    EXPECT_DOUBLE_EQ(pair.stamp_est_1_s - pair.stamp_est_0_s, 1.0);
    EXPECT_EQ(pair.stamp_gt_0_s, pair.stamp_est_0_s);
  }
}

TEST(Rpe, DriftIsPerSecondForOtherDeltas) {
  const Trajectory truth = straight_line(0.5, 30.0, kTruthPeriod_s);
  const Trajectory estimate = straight_line(0.55, 30.0, kEstimatePeriod_s);
  RpeOptions options;
  options.delta_s = 2.0;
  const Result<RpeResult> rpe = compute_rpe(truth, estimate, options);
  ASSERT_TRUE(rpe.ok()) << rpe.error();
  EXPECT_NEAR(rpe.value().translation_m_per_s.rmse, 0.05, 1e-9);
  EXPECT_NEAR(rpe.value().pairs.front().translation_m, 0.1, 1e-9);
  EXPECT_EQ(rpe.value().delta_s, 2.0);
}

TEST(Rpe, ConstantRotationalDriftIsItsRate) {
  const Trajectory truth = turning_on_the_spot(10.0, 20.0, kTruthPeriod_s);
  const Trajectory estimate = turning_on_the_spot(12.5, 20.0, kEstimatePeriod_s);
  const Result<RpeResult> rpe = compute_rpe(truth, estimate);
  ASSERT_TRUE(rpe.ok()) << rpe.error();
  EXPECT_NEAR(rpe.value().rotation_deg_per_s.rmse, 2.5, 1e-9);
  EXPECT_NEAR(rpe.value().rotation_deg_per_s.median, 2.5, 1e-9);
  EXPECT_LT(rpe.value().translation_m_per_s.max, 1e-12);
}

TEST(Rpe, TranslationErrorIsTheDifferenceOfRelativeMotions) {
  // Sturm et al.'s E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j): a rotation error alone leaves no
  // translation error when both relative translations are the same.
  Trajectory truth;
  Trajectory estimate;
  for (int k = 0; k <= 200; ++k) {
    const double t = k * kEstimatePeriod_s;
    const Eigen::Vector3d p(0.3 * t, 0.0, 0.0);
    truth.push_back({t, make_pose(p, Eigen::Quaterniond::Identity())});
    // Rotates about x, the direction of travel: the body-frame motion stays (0.3 t, 0, 0).
    estimate.push_back({t, make_pose(p, Eigen::Quaterniond(Eigen::AngleAxisd(
                                            0.05 * t, Eigen::Vector3d::UnitX())))});
  }
  const Result<RpeResult> rpe = compute_rpe(truth, estimate);
  ASSERT_TRUE(rpe.ok()) << rpe.error();
  EXPECT_LT(rpe.value().translation_m_per_s.max, 1e-12);
  EXPECT_NEAR(rpe.value().rotation_deg_per_s.rmse, 0.05 * 180.0 / std::numbers::pi, 1e-9);
}

TEST(Rpe, PairsFollowEvaluateRpeRules) {
  // 2 s at 16 Hz: 33 poses. For i >= 16 the pose nearest stamp_i + 1 s is the last one, and
  // evaluate_rpe.py drops such pairs, so exactly i = 0..15 remain.
  const Trajectory truth = straight_line(0.5, 2.0, kTruthPeriod_s);
  const Trajectory estimate = straight_line(0.5, 2.0, kEstimatePeriod_s);
  ASSERT_EQ(estimate.size(), 33U);
  const Result<RpeResult> rpe = compute_rpe(truth, estimate);
  ASSERT_TRUE(rpe.ok()) << rpe.error();
  ASSERT_EQ(rpe.value().pairs.size(), 16U);
  EXPECT_EQ(rpe.value().pairs.back().stamp_est_0_s, estimate[15].stamp_s);
  EXPECT_EQ(rpe.value().pairs.back().stamp_est_1_s, estimate[31].stamp_s);
}

TEST(Rpe, UnsortedAndDuplicatedInputIsSortedFirst) {
  const Trajectory truth = straight_line(0.5, 10.0, kTruthPeriod_s);
  const Trajectory estimate = straight_line(0.55, 10.0, kEstimatePeriod_s);
  Trajectory shuffled(estimate.rbegin(), estimate.rend());
  // A duplicate stamp whose earlier copy is wrong: the last one in input order counts.
  shuffled.insert(shuffled.begin(),
                  {estimate[40].stamp_s, make_pose({99.0, 0, 0}, Eigen::Quaterniond::Identity())});
  const Result<RpeResult> sorted_rpe = compute_rpe(truth, estimate);
  const Result<RpeResult> shuffled_rpe = compute_rpe(truth, shuffled);
  ASSERT_TRUE(sorted_rpe.ok() && shuffled_rpe.ok());
  EXPECT_EQ(sorted_rpe.value().pairs.size(), shuffled_rpe.value().pairs.size());
  EXPECT_NEAR(shuffled_rpe.value().translation_m_per_s.max, 0.05, 1e-9);
}

TEST(Rpe, PairsWithoutNearbyGroundTruthAreSkipped) {
  Trajectory truth = straight_line(0.5, 20.0, kTruthPeriod_s);
  // Remove ground truth between 5 s and 7 s: estimate poses there have none within
  // 2 x 1/64 s (twice the median interval).
  std::erase_if(truth,
                [](const StampedPose& p) { return p.stamp_s > 1005.0 && p.stamp_s < 1007.0; });
  const Trajectory estimate = straight_line(0.55, 20.0, kEstimatePeriod_s);
  const Result<RpeResult> full = compute_rpe(straight_line(0.5, 20.0, kTruthPeriod_s), estimate);
  const Result<RpeResult> gapped = compute_rpe(truth, estimate);
  ASSERT_TRUE(full.ok() && gapped.ok());
  EXPECT_LT(gapped.value().pairs.size(), full.value().pairs.size());
  for (const RpePair& pair : gapped.value().pairs) {
    EXPECT_LE(std::abs(pair.stamp_gt_0_s - pair.stamp_est_0_s), 2.0 * kTruthPeriod_s);
    EXPECT_LE(std::abs(pair.stamp_gt_1_s - pair.stamp_est_1_s), 2.0 * kTruthPeriod_s);
  }
  EXPECT_NEAR(gapped.value().translation_m_per_s.rmse, 0.05, 1e-9);
}

TEST(Rpe, TrajectoryShorterThanDeltaHasNoPairs) {
  const Trajectory truth = straight_line(0.5, 5.0, kTruthPeriod_s);
  const Trajectory estimate = straight_line(0.5, 0.75, kEstimatePeriod_s);
  const Result<RpeResult> rpe = compute_rpe(truth, estimate);
  ASSERT_FALSE(rpe.ok());
  EXPECT_NE(rpe.error().find("no pose pairs 1.000000 s apart"), std::string::npos) << rpe.error();
}

TEST(Rpe, BadInputFailsWithAReason) {
  const Trajectory truth = straight_line(0.5, 5.0, kTruthPeriod_s);
  EXPECT_NE(compute_rpe(truth, {}).error().find("estimate has fewer than 2 poses"),
            std::string::npos);
  EXPECT_NE(compute_rpe({}, truth).error().find("ground truth has fewer than 2 poses"),
            std::string::npos);
  RpeOptions bad;
  bad.delta_s = 0.0;
  EXPECT_NE(compute_rpe(truth, truth, bad).error().find("delta_s"), std::string::npos);
  bad.delta_s = std::nan("");
  EXPECT_FALSE(compute_rpe(truth, truth, bad).ok());
}

TEST(Rpe, TumFreiburg1XyzRgbdslamFixture) {
  const std::filesystem::path dir = test::shared_trajectories_dir();
  if (!std::filesystem::exists(dir / "freiburg1_xyz-groundtruth.txt") ||
      !std::filesystem::exists(dir / "freiburg1_xyz-rgbdslam.txt")) {
    GTEST_SKIP() << "shared trajectories not found in " << dir
                 << " (set RANKSLAM_SHARED_DATA to the shared data folder)";
  }
  const Result<Trajectory> truth = read_tum_trajectory(dir / "freiburg1_xyz-groundtruth.txt");
  const Result<Trajectory> estimate = read_tum_trajectory(dir / "freiburg1_xyz-rgbdslam.txt");
  ASSERT_TRUE(truth.ok() && estimate.ok());
  const Result<RpeResult> rpe = compute_rpe(truth.value(), estimate.value());
  ASSERT_TRUE(rpe.ok()) << rpe.error();
  // evaluate_rpe.py's pair selection (--fixed_delta --delta 1 --max_pairs 0) with Sturm et al.'s
  // error order, in numpy on the same files: 753 pairs, translation rmse 0.0215537804 m,
  // rotation rmse 0.9344804594 deg, max 0.0506117485 m and 2.2959854451 deg.
  EXPECT_EQ(rpe.value().translation_m_per_s.count, 753U);
  EXPECT_NEAR(rpe.value().translation_m_per_s.rmse, 0.0215537804, 1e-9);
  EXPECT_NEAR(rpe.value().translation_m_per_s.max, 0.0506117485, 1e-9);
  EXPECT_NEAR(rpe.value().rotation_deg_per_s.rmse, 0.9344804594, 1e-7);
  EXPECT_NEAR(rpe.value().rotation_deg_per_s.max, 2.2959854451, 1e-7);
}

}  // namespace
}  // namespace rankslam::eval
