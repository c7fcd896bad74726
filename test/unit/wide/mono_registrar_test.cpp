// wide::MonoRegistrar on synthetic features: points of an RGB-D frame, the rays a wide-angle
// camera sees them along (beyond 90° from its axis too), descriptors that match them, and wrong
// matches among them.
#include "rankslam/wide/mono_registrar.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace rankslam::wide {
namespace {

struct Scene {
  RgbdFeatures rgbd;
  WideFeatures wide;
  Eigen::Isometry3d T_wide_rgbd = Eigen::Isometry3d::Identity();
};

/// `points` RGB-D features, each matching one wide-angle feature along a ray with 1 mrad of noise
/// (noiseless rays leave MSSE's scale at rounding level, where the inlier count is the compiler's
/// choice); every third wide-angle feature's ray points elsewhere (a wrong match).
Scene make_scene(int points, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 1e-3);
  std::uniform_real_distribution<float> value(0.0F, 100.0F);
  Scene scene;
  scene.T_wide_rgbd.linear() = Eigen::AngleAxisd(1.5, Eigen::Vector3d(0.1, 1.0, 0.2).normalized()).toRotationMatrix();
  scene.T_wide_rgbd.translation() = Eigen::Vector3d(0.4, -0.1, 0.3);
  scene.rgbd.count = scene.wide.count = points;
  scene.rgbd.points.resize(3, points);
  scene.wide.rays.resize(3, points);
  scene.rgbd.descriptors.create(points, 128, CV_32F);
  scene.wide.descriptors.create(points, 128, CV_32F);
  for (int i = 0; i < points; ++i) {
    const Eigen::Vector3d p(1.5 * unit(rng), unit(rng), 2.5 + unit(rng));
    scene.rgbd.points.col(i) = p;
    const Eigen::Vector3d elsewhere(unit(rng), unit(rng), unit(rng));
    const Eigen::Vector3d seen =
        (scene.T_wide_rgbd * p).normalized() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    scene.wide.rays.col(i) = i % 3 == 2 ? elsewhere.normalized() : seen.normalized();
    for (int d = 0; d < 128; ++d) scene.rgbd.descriptors.at<float>(i, d) = value(rng);
    scene.rgbd.descriptors.row(i).copyTo(scene.wide.descriptors.row(i));
  }
  return scene;
}

TEST(MonoRegistrar, FindsThePoseThroughWrongMatchesAndRaysBeyondNinetyDegrees) {
  const Scene scene = make_scene(90, 3);
  int behind = 0;
  for (int i = 0; i < scene.wide.count; ++i) behind += scene.wide.rays(2, i) < 0.0 ? 1 : 0;
  ASSERT_GT(behind, 10) << "the scene puts rays beyond 90 degrees";
  MonoRegistrar registrar;
  const MonoRegistration r = registrar.register_frames(scene.rgbd, scene.wide);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.matches, 90);
  // The 30 wrong matches are off by radians: none is an inlier, and few right ones fall beyond
  // MSSE's 2.5 σ.
  EXPECT_LE(r.inliers, 60);
  EXPECT_GE(r.inliers, 55);
  EXPECT_LT((r.T_wide_rgbd.translation() - scene.T_wide_rgbd.translation()).norm(), 0.01);
  EXPECT_LT(Eigen::AngleAxisd(r.T_wide_rgbd.linear().transpose() * scene.T_wide_rgbd.linear()).angle(), 2e-3);
}

TEST(MonoRegistrar, EachRegistrationStandsAlone) {
  const Scene first = make_scene(90, 3);
  const Scene second = make_scene(40, 4);
  MonoRegistrar registrar;
  const MonoRegistration alone = MonoRegistrar().register_frames(second.rgbd, second.wide);
  (void)registrar.register_frames(first.rgbd, first.wide);
  const MonoRegistration after = registrar.register_frames(second.rgbd, second.wide);
  EXPECT_EQ(after.matches, alone.matches) << "matches of an earlier pair leak into the next";
  EXPECT_EQ(after.inliers, alone.inliers);
  EXPECT_TRUE(after.T_wide_rgbd.isApprox(alone.T_wide_rgbd));
}

TEST(MonoRegistrar, APoseItsInliersLeaveLooseIsRefused) {
  // 40 points in a 10 cm cluster 4 m away, rays with 3 mrad of noise (about 1.5 px on a view):
  // the direction is sure, the distance along it is not.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 3e-3);
  std::uniform_real_distribution<float> value(0.0F, 100.0F);
  constexpr int kPoints = 40;
  RgbdFeatures rgbd;
  WideFeatures wide;
  rgbd.count = wide.count = kPoints;
  rgbd.points.resize(3, kPoints);
  wide.rays.resize(3, kPoints);
  rgbd.descriptors.create(kPoints, 128, CV_32F);
  wide.descriptors.create(kPoints, 128, CV_32F);
  for (int i = 0; i < kPoints; ++i) {
    const Eigen::Vector3d p = Eigen::Vector3d(0.0, 0.0, 4.0) + 0.05 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    rgbd.points.col(i) = p;
    wide.rays.col(i) = (p.normalized() + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))).normalized();
    for (int d = 0; d < 128; ++d) rgbd.descriptors.at<float>(i, d) = value(rng);
    rgbd.descriptors.row(i).copyTo(wide.descriptors.row(i));
  }
  MonoRegistrar registrar;
  const MonoRegistration r = registrar.register_frames(rgbd, wide);
  EXPECT_GE(r.inliers, 12) << "enough inliers";
  EXPECT_GT(r.position_sigma_m, 0.03);
  EXPECT_FALSE(r.ok) << "but they leave the translation loose";
  // The same inliers spread over the field fix it.
  const Scene spread = make_scene(40, 6);
  const MonoRegistration fixed = registrar.register_frames(spread.rgbd, spread.wide);
  EXPECT_TRUE(fixed.ok);
  EXPECT_LT(fixed.position_sigma_m, 0.01) << "against the loose pose's " << r.position_sigma_m;
}

TEST(MonoRegistrar, TooFewFeaturesRegisterNothing) {
  const Scene scene = make_scene(11, 5);
  const MonoRegistration r = MonoRegistrar().register_frames(scene.rgbd, scene.wide);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.inliers, 0);
}

}  // namespace
}  // namespace rankslam::wide
