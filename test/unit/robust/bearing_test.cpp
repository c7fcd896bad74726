// P3P (solve_p3p) and the bearing model under MSSE: camera poses from points and the rays a
// 190° lens sees them along, beyond 90° from the axis included.
#include "rankslam/robust/bearing.hpp"
#include "rankslam/robust/msse.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace rankslam::robust {
namespace {

Eigen::Isometry3d random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(Eigen::Vector4d(unit(rng), unit(rng), unit(rng), unit(rng)).normalized())
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
  return T;
}

/// A point 0.5–5 m from the camera of T_c_w, up to `max_angle` from its axis, in frame w.
Eigen::Vector3d point_seen(const Eigen::Isometry3d& T_c_w, double max_angle, std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(0.0, max_angle);
  std::uniform_real_distribution<double> azimuth(-M_PI, M_PI);
  std::uniform_real_distribution<double> range(0.5, 5.0);
  const double a = angle(rng);
  const double b = azimuth(rng);
  const Eigen::Vector3d ray(std::sin(a) * std::cos(b), std::sin(a) * std::sin(b), std::cos(a));
  return T_c_w.inverse() * (range(rng) * ray);
}

double rotation_error_rad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

TEST(SolveP3p, OneOfTheSolutionsIsTheTruePose) {
  std::mt19937 rng(11);
  int solved = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Isometry3d T_c_w = random_pose(rng);
    std::array<Eigen::Vector3d, 3> points;
    std::array<Eigen::Vector3d, 3> bearings;
    for (std::size_t i = 0; i < 3; ++i) {
      points[i] = point_seen(T_c_w, 95.0 * M_PI / 180.0, rng);
      bearings[i] = (T_c_w * points[i]).normalized();
    }
    std::array<Eigen::Isometry3d, 4> poses;
    const int count = solve_p3p(points, bearings, poses);
    double best = 1e9;
    for (int i = 0; i < count; ++i) {
      const auto& T = poses[static_cast<std::size_t>(i)];
      best = std::min(best, (T.translation() - T_c_w.translation()).norm() + rotation_error_rad(T, T_c_w));
    }
    solved += best < 1e-6 ? 1 : 0;
  }
  // Near-degenerate random triples (points almost on the danger cylinder) may lose precision.
  EXPECT_GE(solved, 495);
}

TEST(SolveP3p, DegenerateTriplesGiveNothing) {
  std::array<Eigen::Isometry3d, 4> poses;
  const Eigen::Vector3d p(0.0, 0.0, 2.0);
  EXPECT_EQ(solve_p3p({p, p, Eigen::Vector3d(1.0, 0.0, 2.0)},
                      {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ(), Eigen::Vector3d(1.0, 0.0, 2.0).normalized()},
                      poses),
            0);
}

TEST(BearingModel, MsseFindsThePoseAmongHalfOutliersAcrossAWideField) {
  std::mt19937 rng(5);
  constexpr int kPoints = 400;
  std::normal_distribution<double> noise(0.0, 1e-3);  // about 0.2 px at 230 px/rad
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::Isometry3d T_c_w = random_pose(rng);
    Eigen::Matrix3Xd points(3, kPoints);
    Eigen::Matrix3Xd bearings(3, kPoints);
    for (int i = 0; i < kPoints; ++i) {
      points.col(i) = point_seen(T_c_w, 95.0 * M_PI / 180.0, rng);
      Eigen::Vector3d b = (T_c_w * points.col(i)).normalized();
      if (i % 2 == 1) {
        b = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();  // a wrong match
      } else {
        b = (b + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))).normalized();
      }
      bearings.col(i) = b;
    }
    BearingModel model(kPoints);
    ASSERT_EQ(model.set_correspondences(points, bearings), RobustStatus::kOk);
    RobustWorkspace workspace(kPoints);
    MsseConfig config;
    config.seed = static_cast<std::uint64_t>(trial + 1);
    const auto result = estimate_msse(model, config, workspace);
    ASSERT_TRUE(result.ok());
    EXPECT_LT((result.model.translation() - T_c_w.translation()).norm(), 5e-3) << "trial " << trial;
    EXPECT_LT(rotation_error_rad(result.model, T_c_w), 1e-3) << "trial " << trial;
    int wrong = 0;
    for (const int i : result.inliers) wrong += i % 2;
    EXPECT_GE(result.inlier_count, 180) << "trial " << trial;
    EXPECT_LE(wrong, 2) << "trial " << trial;
  }
}

TEST(BearingModel, RejectsBadInput) {
  BearingModel model(4);
  Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Ones(3, 4);
  Eigen::Matrix3Xd bearings = Eigen::Matrix3Xd::Ones(3, 4);
  bearings.col(2).setZero();
  EXPECT_EQ(model.set_correspondences(points, bearings), RobustStatus::kInvalidInput);
  EXPECT_EQ(model.size(), 0);
  EXPECT_EQ(model.set_correspondences(Eigen::Matrix3Xd::Ones(3, 5), Eigen::Matrix3Xd::Ones(3, 5)),
            RobustStatus::kCapacityExceeded);
}

}  // namespace
}  // namespace rankslam::robust
