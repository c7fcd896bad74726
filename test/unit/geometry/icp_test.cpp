#include "rankslam/geometry/icp.hpp"

#include "synthetic_scene.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace rankslam::geometry {
namespace {

// A wall facing the camera at `depth_m`, sampled every 4 cm, with its normal towards the camera
// and each point's pixel.
struct Wall {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;
  std::vector<Eigen::Vector2f> pixels;

  Wall(float depth_m, const PlaneIcp& icp) {
    for (float y = -0.6F; y <= 0.6F; y += 0.04F) {
      for (float x = -0.8F; x <= 0.8F; x += 0.04F) {
        points.emplace_back(x, y, depth_m);
        normals.emplace_back(0.0F, 0.0F, -1.0F);
        pixels.push_back(icp.project(points.back()));
      }
    }
  }
  [[nodiscard]] IcpCloud cloud() const { return {points, normals, pixels, {}}; }
};

IcpConfig plain_config() {
  IcpConfig config;
  config.max_iterations = 10;
  config.max_points = 2000;
  config.max_distance_m = 0.1F;
  return config;
}

// One plane fixes its distance and tilt; a shift along it and a turn about its normal leave the
// residuals unchanged. The prior decides those, the data the rest.
TEST(PlaneIcpPrior, OnOnePlaneTheDataFixTheDistanceAndThePriorTheShiftAlongIt) {
  PlaneIcp icp;
  ASSERT_TRUE(icp.configure(testing::test_calibration(), 2000).empty());
  const Wall previous(1.5F, icp);
  // The camera moved 2 cm towards the wall: the current points are 2 cm nearer.
  const Wall current(1.48F, icp);
  Eigen::Isometry3d start = Eigen::Isometry3d::Identity();

  IcpConfig config = plain_config();
  // Without a prior the in-plane directions have no information at all: no solution.
  EXPECT_FALSE(icp.refine(previous.cloud(), current.cloud(), start, config).ok);

  for (const double prior_shift_m : {0.0, 0.03}) {
    config.prior.T_previous_current = Eigen::Isometry3d::Identity();
    config.prior.T_previous_current.translation() = Eigen::Vector3d(prior_shift_m, 0.0, 0.0);
    // Unweighted residuals: the information is in units of one point's (1 m⁻²); a hundredth of
    // a point's is nothing next to the wall's 1 200 points, yet decides where they say nothing.
    config.prior.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e-2;
    const IcpResult result = icp.refine(previous.cloud(), current.cloud(), start, config);
    ASSERT_TRUE(result.ok) << "prior shift " << prior_shift_m;
    EXPECT_NEAR(result.T_previous_current.translation().z(), 0.02, 1e-4) << "prior shift " << prior_shift_m;
    EXPECT_NEAR(result.T_previous_current.translation().x(), prior_shift_m, 1e-3) << "prior shift " << prior_shift_m;
    EXPECT_NEAR(result.T_previous_current.translation().y(), 0.0, 1e-3);
    EXPECT_LT(Eigen::AngleAxisd(result.T_previous_current.rotation()).angle(), 1e-3);
  }

  // A prior that contradicts the data where the plane constrains the motion gives way to it.
  config.prior.T_previous_current = Eigen::Isometry3d::Identity();
  config.prior.T_previous_current.translation() = Eigen::Vector3d(0.0, 0.0, -0.05);
  const IcpResult result = icp.refine(previous.cloud(), current.cloud(), start, config);
  ASSERT_TRUE(result.ok);
  EXPECT_NEAR(result.T_previous_current.translation().z(), 0.02, 1e-3);
}

}  // namespace
}  // namespace rankslam::geometry
