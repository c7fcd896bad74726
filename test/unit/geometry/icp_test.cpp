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

// A prior that disagrees with the data where they measure the motion wins a share of it when
// taken whole (the least squares meet between them); kept only where the data are weak, it
// leaves the measured distance to the data and still holds the shift along the wall.
TEST(PlaneIcpPrior, KeptWhereTheDataAreWeakAPriorNoLongerPullsWhereTheyMeasure) {
  PlaneIcp icp;
  ASSERT_TRUE(icp.configure(testing::test_calibration(), 2000).empty());
  const Wall previous(1.5F, icp);
  const Wall current(1.48F, icp);
  IcpConfig config = plain_config();
  config.prior.T_previous_current = Eigen::Isometry3d::Identity();
  config.prior.T_previous_current.translation() = Eigen::Vector3d(0.03, 0.0, -0.2);
  // A hundredth of the wall's 1 200 points along the normal, and all there is along the wall.
  config.prior.information = Eigen::Matrix<double, 6, 6>::Identity() * 12.0;

  config.prior_crossover = 0.0;
  const IcpResult whole = icp.refine(previous.cloud(), current.cloud(), Eigen::Isometry3d::Identity(), config);
  ASSERT_TRUE(whole.ok);
  // (1 200 · 0.02 − 12 · 0.2) / 1 212 = 0.0178 m.
  EXPECT_NEAR(whole.T_previous_current.translation().z(), 0.0178, 5e-4);

  config.prior_crossover = 1.0;
  const IcpResult kept = icp.refine(previous.cloud(), current.cloud(), Eigen::Isometry3d::Identity(), config);
  ASSERT_TRUE(kept.ok);
  EXPECT_NEAR(kept.T_previous_current.translation().z(), 0.02, 1e-4);
  EXPECT_NEAR(kept.T_previous_current.translation().x(), 0.03, 1e-3);
}

// A surface near the pass-through is measured nearer than it is (the cut keeps only the samples
// whose noise fell short of it). Points deeper than the ICP's depth limit take no part: here a
// far wall that appears to have come 1 cm nearer while the near one came the true 2 cm.
TEST(PlaneIcpDepthLimit, PointsBeyondTheLimitTakeNoPart) {
  PlaneIcp icp;
  ASSERT_TRUE(icp.configure(testing::test_calibration(), 4000).empty());
  const Wall near_previous(1.5F, icp);
  const Wall near_current(1.48F, icp);
  const Wall far_previous(3.0F, icp);
  const Wall far_current(2.99F, icp);
  // The near wall on the left half of the view, the far one on the right.
  struct Cloud {
    std::vector<Eigen::Vector3f> points;
    std::vector<Eigen::Vector3f> normals;
    std::vector<Eigen::Vector2f> pixels;
    void add(const Wall& wall, bool left) {
      for (std::size_t i = 0; i < wall.points.size(); ++i) {
        if ((wall.pixels[i].x() < 320.0F) != left) continue;
        points.push_back(wall.points[i]);
        normals.push_back(wall.normals[i]);
        pixels.push_back(wall.pixels[i]);
      }
    }
    [[nodiscard]] IcpCloud cloud() const { return {points, normals, pixels, {}}; }
  };
  Cloud previous;
  Cloud current;
  previous.add(near_previous, true);
  previous.add(far_previous, false);
  current.add(near_current, true);
  current.add(far_current, false);
  int near_points = 0;
  for (const Eigen::Vector3f& p : current.points) near_points += p.z() < 2.0F ? 1 : 0;
  ASSERT_GT(near_points, 50);
  ASSERT_GT(static_cast<int>(current.points.size()) - near_points, 50);

  IcpConfig config = plain_config();
  config.max_points = 4000;
  config.prior.T_previous_current = Eigen::Isometry3d::Identity();
  config.prior.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e-2;
  const Eigen::Isometry3d start = Eigen::Isometry3d::Identity();

  const IcpResult both = icp.refine(previous.cloud(), current.cloud(), start, config);
  ASSERT_TRUE(both.ok);
  EXPECT_GT(both.associations, near_points);

  config.max_depth_m = 2.5F;
  const IcpResult near_only = icp.refine(previous.cloud(), current.cloud(), start, config);
  ASSERT_TRUE(near_only.ok);
  EXPECT_LE(near_only.associations, near_points);
  EXPECT_NEAR(near_only.T_previous_current.translation().z(), 0.02, 1e-4);

  // Nothing within the limit: no registration.
  config.max_depth_m = 1.0F;
  EXPECT_FALSE(icp.refine(previous.cloud(), current.cloud(), start, config).ok);
}

// Along a direction where the data carry λ times the prior's information the prior keeps
// τ/(τ+λ) of its own; where they carry none it is whole.
TEST(PlaneIcpPrior, PriorIsKeptInProportionToHowWeakTheDataAre) {
  Eigen::Matrix<double, 6, 6> data = Eigen::Matrix<double, 6, 6>::Zero();
  data(5, 5) = 300.0;  // the data measure z alone
  data(0, 0) = 1.0;
  const Eigen::Matrix<double, 6, 6> prior = Eigen::Matrix<double, 6, 6>::Identity() * 3.0;
  const Eigen::Matrix<double, 6, 6> kept = prior_where_data_are_weak(data, prior, 1.0);
  EXPECT_NEAR(kept(5, 5), 3.0 * 1.0 / (1.0 + 100.0), 1e-9);
  EXPECT_NEAR(kept(0, 0), 3.0 * 1.0 / (1.0 + 1.0 / 3.0), 1e-9);
  EXPECT_NEAR(kept(3, 3), 3.0, 1e-9);
  EXPECT_NEAR(kept(3, 5), 0.0, 1e-9);
  EXPECT_LT((prior_where_data_are_weak(data, prior, 0.0) - prior).norm(), 1e-12);
}

}  // namespace
}  // namespace rankslam::geometry
