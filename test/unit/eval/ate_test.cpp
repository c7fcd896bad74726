#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "rankslam/eval/metrics.hpp"
#include "test_support.hpp"

namespace rankslam::eval {
namespace {

using test::helix;
using test::make_pose;

Eigen::Isometry3d some_rigid_transform() {
  return make_pose({2.0, -1.0, 0.5}, Eigen::Quaterniond(Eigen::AngleAxisd(
                                         0.7, Eigen::Vector3d(0.3, -0.5, 0.8).normalized())));
}

/// Horn (1987), closed-form absolute orientation with unit quaternions: the eigenvector of the
/// largest eigenvalue of N. An independent check of the SVD solution used by compute_ate().
Eigen::Isometry3d horn_alignment(const std::vector<Eigen::Vector3d>& from,
                                 const std::vector<Eigen::Vector3d>& to) {
  Eigen::Vector3d from_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d to_mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    from_mean += from[i];
    to_mean += to[i];
  }
  from_mean /= static_cast<double>(from.size());
  to_mean /= static_cast<double>(to.size());
  Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    s += (from[i] - from_mean) * (to[i] - to_mean).transpose();
  }
  Eigen::Matrix4d n;
  n << s(0, 0) + s(1, 1) + s(2, 2), s(1, 2) - s(2, 1), s(2, 0) - s(0, 2), s(0, 1) - s(1, 0),
      s(1, 2) - s(2, 1), s(0, 0) - s(1, 1) - s(2, 2), s(0, 1) + s(1, 0), s(2, 0) + s(0, 2),
      s(2, 0) - s(0, 2), s(0, 1) + s(1, 0), -s(0, 0) + s(1, 1) - s(2, 2), s(1, 2) + s(2, 1),
      s(0, 1) - s(1, 0), s(2, 0) + s(0, 2), s(1, 2) + s(2, 1), -s(0, 0) - s(1, 1) + s(2, 2);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> solver(n);
  const Eigen::Vector4d q = solver.eigenvectors().col(3);
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = Eigen::Quaterniond(q(0), q(1), q(2), q(3)).normalized().toRotationMatrix();
  transform.translation() = to_mean - transform.linear() * from_mean;
  return transform;
}

TEST(ErrorStats, MatchesNumpyDefinitions) {
  const std::vector<double> even = {4.0, 1.0, 3.0, 2.0};
  const ErrorStats stats = compute_error_stats(even);
  EXPECT_EQ(stats.count, 4U);
  EXPECT_DOUBLE_EQ(stats.mean, 2.5);
  EXPECT_DOUBLE_EQ(stats.median, 2.5);
  EXPECT_DOUBLE_EQ(stats.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(stats.stddev, std::sqrt(1.25));  // population, numpy.std's default
  EXPECT_DOUBLE_EQ(stats.min, 1.0);
  EXPECT_DOUBLE_EQ(stats.max, 4.0);
  const std::vector<double> odd = {5.0, 1.0, 3.0};
  EXPECT_DOUBLE_EQ(compute_error_stats(odd).median, 3.0);
  EXPECT_EQ(compute_error_stats(std::vector<double>{}).count, 0U);
}

TEST(Ate, IdenticalTrajectoriesHaveZeroError) {
  const Trajectory truth = helix(100.0, 20.0, 100.0);
  const Result<AteResult> ate = compute_ate(truth, truth);
  ASSERT_TRUE(ate.ok()) << ate.error();
  EXPECT_EQ(ate.value().translation_m.count, truth.size());
  EXPECT_LT(ate.value().translation_m.rmse, 1e-12);
  EXPECT_LT(ate.value().translation_m.max, 1e-12);
  EXPECT_TRUE(ate.value().T_gtworld_estworld.matrix().isApprox(Eigen::Matrix4d::Identity(), 1e-12));
}

TEST(Ate, RigidOffsetOfTheWholeEstimateIsAlignedAway) {
  const Trajectory truth = helix(100.0, 20.0, 100.0);
  const Eigen::Isometry3d T_est_gt = some_rigid_transform();
  // The estimate: another world frame, and sampled at 30 Hz with 4 ms stamp offset.
  Trajectory estimate;
  for (std::size_t k = 0; k < truth.size(); k += 3) {
    estimate.push_back({truth[k].stamp_s + 0.004, T_est_gt * truth[k].T_world_cam});
  }
  const Result<AteResult> ate = compute_ate(truth, estimate);
  ASSERT_TRUE(ate.ok()) << ate.error();
  const AteResult& result = ate.value();
  EXPECT_EQ(result.translation_m.count, estimate.size());
  EXPECT_LT(result.translation_m.rmse, 1e-9);
  EXPECT_TRUE(result.T_gtworld_estworld.matrix().isApprox(T_est_gt.inverse().matrix(), 1e-9));
  ASSERT_EQ(result.aligned_estimate.size(), estimate.size());
  for (std::size_t k = 0; k < estimate.size(); ++k) {
    EXPECT_TRUE(result.aligned_estimate[k].T_world_cam.matrix().isApprox(
        truth[3 * k].T_world_cam.matrix(), 1e-9))
        << k;
    EXPECT_EQ(result.aligned_estimate[k].stamp_s, estimate[k].stamp_s);
  }
  // Matches are sorted by stamp and point at the right poses.
  for (std::size_t k = 0; k < result.matches.size(); ++k) {
    EXPECT_EQ(result.matches[k].first_index, 3 * k);
    EXPECT_EQ(result.matches[k].second_index, k);
  }
}

TEST(Ate, KnownNoiseGivesItsRmse) {
  // Each ground-truth position is visited twice, the estimate is off by +r d and -r d there:
  // the offsets sum to zero and are uncorrelated with position, so the best alignment is the
  // identity (up to the rigid offset added on top) and every error is exactly r.
  const double noise_m = 0.013;
  const Trajectory path = helix(0.0, 10.0, 50.0);
  Trajectory truth;
  Trajectory estimate;
  const Eigen::Isometry3d T_est_gt = some_rigid_transform();
  for (std::size_t k = 0; k < path.size(); ++k) {
    const Eigen::Vector3d d =
        Eigen::Vector3d(std::cos(1.3 * k), std::sin(0.7 * k), 0.5).normalized();
    for (int sign : {1, -1}) {
      const double t = 2.0 * static_cast<double>(truth.size()) * 0.01;
      truth.push_back({t, path[k].T_world_cam});
      Eigen::Isometry3d noisy = path[k].T_world_cam;
      noisy.translation() += sign * noise_m * d;
      estimate.push_back({t + 0.001, T_est_gt * noisy});
    }
  }
  const Result<AteResult> ate = compute_ate(truth, estimate);
  ASSERT_TRUE(ate.ok()) << ate.error();
  const ErrorStats& stats = ate.value().translation_m;
  EXPECT_EQ(stats.count, truth.size());
  EXPECT_NEAR(stats.rmse, noise_m, 1e-12);
  EXPECT_NEAR(stats.mean, noise_m, 1e-12);
  EXPECT_NEAR(stats.median, noise_m, 1e-12);
  EXPECT_NEAR(stats.min, noise_m, 1e-12);
  EXPECT_NEAR(stats.max, noise_m, 1e-12);
  EXPECT_LT(stats.stddev, 1e-12);
}

TEST(Ate, GaussianNoiseAgreesWithHornsQuaternionSolution) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise_m(0.0, 0.01);
  const Trajectory truth = helix(50.0, 200.0, 100.0);  // 20 001 poses
  const Eigen::Isometry3d T_est_gt = some_rigid_transform();
  Trajectory estimate;
  std::vector<Eigen::Vector3d> from;
  std::vector<Eigen::Vector3d> to;
  for (const StampedPose& pose : truth) {
    Eigen::Isometry3d noisy = T_est_gt * pose.T_world_cam;
    noisy.translation() += Eigen::Vector3d(noise_m(rng), noise_m(rng), noise_m(rng));
    estimate.push_back({pose.stamp_s, noisy});
    from.push_back(noisy.translation());
    to.push_back(pose.T_world_cam.translation());
  }
  const Result<AteResult> ate = compute_ate(truth, estimate);
  ASSERT_TRUE(ate.ok()) << ate.error();
  const Eigen::Isometry3d horn = horn_alignment(from, to);
  EXPECT_TRUE(ate.value().T_gtworld_estworld.matrix().isApprox(horn.matrix(), 1e-9));
  double sum_squares = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i)
    sum_squares += (horn * from[i] - to[i]).squaredNorm();
  EXPECT_NEAR(ate.value().translation_m.rmse,
              std::sqrt(sum_squares / static_cast<double>(from.size())), 1e-10);
  // And the RMSE is what the noise says: sigma * sqrt(3), less a little for the 6 fitted
  // degrees of freedom.
  EXPECT_NEAR(ate.value().translation_m.rmse, 0.01 * std::sqrt(3.0), 0.0004);
}

TEST(Ate, OnlyAssociatedStampsCount) {
  const Trajectory truth = helix(0.0, 10.0, 100.0);
  Trajectory estimate;
  for (std::size_t k = 0; k < truth.size(); k += 10) estimate.push_back(truth[k]);
  estimate.push_back({50.0, Eigen::Isometry3d::Identity()});  // no ground truth near: ignored
  const Result<AteResult> ate = compute_ate(truth, estimate);
  ASSERT_TRUE(ate.ok()) << ate.error();
  EXPECT_EQ(ate.value().translation_m.count, estimate.size() - 1);
  EXPECT_LT(ate.value().translation_m.rmse, 1e-12);
  EXPECT_EQ(ate.value().aligned_estimate.size(), estimate.size());
}

TEST(Ate, FailsWithAReason) {
  const Trajectory truth = helix(0.0, 2.0, 100.0);
  EXPECT_NE(compute_ate({}, truth).error().find("ground truth has no poses"), std::string::npos);
  EXPECT_NE(compute_ate(truth, {}).error().find("estimate has no poses"), std::string::npos);
  const Result<AteResult> disjoint = compute_ate(truth, helix(10.0, 2.0, 30.0));
  ASSERT_FALSE(disjoint.ok());
  EXPECT_NE(disjoint.error().find("no estimate stamp is within 0.020000 s"), std::string::npos)
      << disjoint.error();
  Trajectory broken = truth;
  broken[3].T_world_cam.translation().x() = std::numeric_limits<double>::infinity();
  EXPECT_NE(compute_ate(truth, broken).error().find("estimate pose 3"), std::string::npos);
  AteOptions bad;
  bad.max_difference_s = -1.0;
  EXPECT_FALSE(compute_ate(truth, truth, bad).ok());
}

TEST(Ate, TooFewAssociatedPosesToAlignAreNoAte) {
  const Trajectory truth = helix(0.0, 2.0, 100.0);
  for (const std::size_t poses : {1U, 2U}) {
    const Trajectory estimate(truth.begin(), truth.begin() + static_cast<std::ptrdiff_t>(poses));
    const Result<AteResult> ate = compute_ate(truth, estimate);
    ASSERT_FALSE(ate.ok()) << poses;
    EXPECT_NE(ate.error().find("at least 3 associated poses"), std::string::npos) << ate.error();
    EXPECT_NE(ate.error().find("found " + std::to_string(poses)), std::string::npos) << ate.error();
  }
  EXPECT_TRUE(compute_ate(truth, Trajectory(truth.begin(), truth.begin() + 3)).ok());
}

TEST(Ate, TumFreiburg1XyzRgbdslamFixture) {
  const std::filesystem::path dir = test::shared_trajectories_dir();
  if (!std::filesystem::exists(dir / "freiburg1_xyz-groundtruth.txt") ||
      !std::filesystem::exists(dir / "freiburg1_xyz-rgbdslam.txt")) {
    GTEST_SKIP() << "shared trajectories not found in " << dir
                 << " (set RANKSLAM_SHARED_DATA to the shared data folder)";
  }
  const Result<Trajectory> truth = read_tum_trajectory(dir / "freiburg1_xyz-groundtruth.txt");
  const Result<Trajectory> estimate = read_tum_trajectory(dir / "freiburg1_xyz-rgbdslam.txt");
  ASSERT_TRUE(truth.ok()) << truth.error();
  ASSERT_TRUE(estimate.ok()) << estimate.error();
  const Result<AteResult> ate = compute_ate(truth.value(), estimate.value());
  ASSERT_TRUE(ate.ok()) << ate.error();
  const ErrorStats& stats = ate.value().translation_m;
  // The figure the TUM benchmark publishes for this estimate (docs/methods.md §12).
  EXPECT_NEAR(stats.rmse, 0.0135, 0.0001);
  // The benchmark's own evaluate_ate.py (numpy) on the same files prints, to 10 decimals:
  // 786 pairs, rmse 0.0134734678, mean 0.0120294764, median 0.0111757511, std 0.0060684456,
  // min 0.0009387027, max 0.0347272017.
  EXPECT_EQ(stats.count, 786U);
  EXPECT_NEAR(stats.rmse, 0.0134734678, 1e-9);
  EXPECT_NEAR(stats.mean, 0.0120294764, 1e-9);
  EXPECT_NEAR(stats.median, 0.0111757511, 1e-9);
  EXPECT_NEAR(stats.stddev, 0.0060684456, 1e-9);
  EXPECT_NEAR(stats.min, 0.0009387027, 1e-9);
  EXPECT_NEAR(stats.max, 0.0347272017, 1e-9);
}

}  // namespace
}  // namespace rankslam::eval
