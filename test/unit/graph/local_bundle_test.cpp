// Local bundle adjustment on a synthetic window: key-frames along a path looking at a cloud of
// landmarks, observed with the depth camera's noise (along the ray the depth error, across it a
// pixel's error at the depth); the solve starts from poses off the truth and must bring their
// relative motion back within the noise, hold the first pose, keep a prior's pose where no
// landmark ties it, and flag gross outliers.

#include "rankslam/graph/local_bundle.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace rankslam::graph {
namespace {

using Matrix6d = LocalBundle::Matrix6d;

constexpr double kAxialPerM = 5e-3;   // σ_z = a·z²
constexpr double kLateralPerM = 1e-3;  // σ_lateral = 0.5 px at f ≈ 500 px, per metre of depth

Eigen::Isometry3d pose(double yaw_rad, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.translation() = t;
  return T;
}

Eigen::Matrix3d whitening(const Eigen::Vector3d& point_cam) {
  const double z = point_cam.z();
  const Eigen::Vector3d ray = point_cam.normalized();
  const Eigen::Vector3d across = ray.unitOrthogonal();
  Eigen::Matrix3d S;
  S.row(0) = ray.transpose() / (kAxialPerM * z * z);
  S.row(1) = across.transpose() / (kLateralPerM * z);
  S.row(2) = ray.cross(across).transpose() / (kLateralPerM * z);
  return S;
}

Eigen::Vector3d noisy(const Eigen::Vector3d& point_cam, std::mt19937& random) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Matrix3d S = whitening(point_cam);
  return point_cam + S.inverse() * Eigen::Vector3d(normal(random), normal(random), normal(random));
}

double translation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}

struct Scene {
  std::vector<Eigen::Isometry3d> truth;
  std::vector<Eigen::Vector3d> landmarks;
};

Scene make_scene(int poses, int landmarks, std::mt19937& random) {
  Scene scene;
  for (int k = 0; k < poses; ++k) scene.truth.push_back(pose(0.05 * k, Eigen::Vector3d(0.1 * k, 0.0, 0.02 * k)));
  std::uniform_real_distribution<double> across(-1.0, 1.0);
  std::uniform_real_distribution<double> depth(1.0, 3.0);
  for (int l = 0; l < landmarks; ++l) scene.landmarks.emplace_back(across(random), 0.6 * across(random), depth(random));
  return scene;
}

LocalBundle configured(int poses, int landmarks) {
  LocalBundle bundle;
  EXPECT_EQ(bundle.configure({poses, landmarks, poses * landmarks, 4 * poses}), "");
  return bundle;
}

TEST(LocalBundle, RecoversTheRelativeMotionFromPosesOffTheTruth) {
  std::mt19937 random(7);
  const Scene scene = make_scene(5, 300, random);
  LocalBundle bundle = configured(5, 300);
  for (int k = 0; k < 5; ++k) {
    // Off by 2 cm and 1° per key-frame after the first.
    const Eigen::Isometry3d off = k == 0 ? Eigen::Isometry3d::Identity() : pose(0.0175, Eigen::Vector3d(0.02, -0.01, 0.01));
    ASSERT_EQ(bundle.add_pose(scene.truth[static_cast<std::size_t>(k)] * off), k);
  }
  for (const Eigen::Vector3d& p : scene.landmarks) {
    const int landmark = bundle.add_landmark(p + Eigen::Vector3d(0.01, 0.01, -0.01));
    for (int k = 0; k < 5; ++k) {
      const Eigen::Vector3d seen = noisy(scene.truth[static_cast<std::size_t>(k)].inverse() * p, random);
      ASSERT_TRUE(bundle.add_observation(k, landmark, seen, whitening(seen)));
    }
  }
  const LocalBundleSummary summary = bundle.solve(20, 2.8);
  ASSERT_TRUE(summary.ok) << summary.message;
  EXPECT_LT(summary.final_cost, summary.initial_cost);
  EXPECT_GT(summary.inlier_observations, 0.9 * bundle.observations());
  EXPECT_EQ(bundle.pose(0).matrix(), scene.truth[0].matrix()) << "the first pose is held";
  for (int k = 1; k < 5; ++k) {
    const Eigen::Isometry3d estimated = bundle.pose(0).inverse() * bundle.pose(k);
    const Eigen::Isometry3d truth = scene.truth[0].inverse() * scene.truth[static_cast<std::size_t>(k)];
    EXPECT_LT(translation_error(estimated, truth), 1e-3) << "key-frame " << k;
  }
}

TEST(LocalBundle, APoseNoLandmarkTiesKeepsItsPrior) {
  std::mt19937 random(11);
  const Scene scene = make_scene(3, 100, random);
  LocalBundle bundle = configured(3, 100);
  for (int k = 0; k < 3; ++k) (void)bundle.add_pose(scene.truth[static_cast<std::size_t>(k)]);
  for (const Eigen::Vector3d& p : scene.landmarks) {
    const int landmark = bundle.add_landmark(p);
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d seen = noisy(scene.truth[static_cast<std::size_t>(k)].inverse() * p, random);
      ASSERT_TRUE(bundle.add_observation(k, landmark, seen, whitening(seen)));
    }
  }
  // Pose 2 has only its prior from pose 1, which says 5 cm further on than the start.
  const Eigen::Isometry3d prior = (scene.truth[1].inverse() * scene.truth[2]) * pose(0.0, Eigen::Vector3d(0.05, 0, 0));
  ASSERT_TRUE(bundle.add_edge(1, 2, prior, Matrix6d::Identity() * 1e6));
  const LocalBundleSummary summary = bundle.solve(20, 2.8);
  ASSERT_TRUE(summary.ok) << summary.message;
  EXPECT_LT(translation_error(bundle.pose(1).inverse() * bundle.pose(2), prior), 1e-3);
}

TEST(LocalBundle, GrossOutliersAreFlaggedAndDoNotPullThePoses) {
  std::mt19937 random(3);
  const Scene scene = make_scene(3, 200, random);
  LocalBundle bundle = configured(3, 200);
  for (int k = 0; k < 3; ++k) (void)bundle.add_pose(scene.truth[static_cast<std::size_t>(k)]);
  int outliers = 0;
  for (std::size_t l = 0; l < scene.landmarks.size(); ++l) {
    const int landmark = bundle.add_landmark(scene.landmarks[l]);
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d seen = noisy(scene.truth[static_cast<std::size_t>(k)].inverse() * scene.landmarks[l], random);
      // One landmark in ten mismatched in the last key-frame: 20 cm off.
      if (k == 2 && l % 10 == 0) {
        seen += Eigen::Vector3d(0.2, 0.0, 0.0);
        ++outliers;
      }
      ASSERT_TRUE(bundle.add_observation(k, landmark, seen, whitening(seen)));
    }
  }
  const LocalBundleSummary summary = bundle.solve(20, 2.8);
  ASSERT_TRUE(summary.ok) << summary.message;
  for (int o = 2; o < bundle.observations(); o += 30) EXPECT_FALSE(bundle.inlier(o)) << "observation " << o;
  EXPECT_LE(summary.inlier_observations, bundle.observations() - outliers);
  EXPECT_LT(translation_error(bundle.pose(0).inverse() * bundle.pose(2), scene.truth[0].inverse() * scene.truth[2]), 2e-3);
}

TEST(LocalBundle, FullOrInvalidInputIsRefused) {
  LocalBundle bundle;
  EXPECT_NE(bundle.configure({1, 10, 10, 0}), "");
  ASSERT_EQ(bundle.configure({2, 1, 2, 1}), "");
  EXPECT_EQ(bundle.add_pose(Eigen::Isometry3d::Identity()), 0);
  EXPECT_EQ(bundle.add_pose(Eigen::Isometry3d::Identity()), 1);
  EXPECT_EQ(bundle.add_pose(Eigen::Isometry3d::Identity()), -1);
  EXPECT_EQ(bundle.add_landmark(Eigen::Vector3d(0, 0, std::nan(""))), -1);
  EXPECT_EQ(bundle.add_landmark(Eigen::Vector3d(0, 0, 1)), 0);
  EXPECT_EQ(bundle.add_landmark(Eigen::Vector3d(0, 0, 2)), -1);
  EXPECT_FALSE(bundle.add_observation(2, 0, Eigen::Vector3d(0, 0, 1), Eigen::Matrix3d::Identity()));
  EXPECT_FALSE(bundle.add_edge(0, 1, Eigen::Isometry3d::Identity(), -Matrix6d::Identity()));
  EXPECT_FALSE(bundle.solve(5, 1.0).ok) << "no observations";
}

}  // namespace
}  // namespace rankslam::graph
