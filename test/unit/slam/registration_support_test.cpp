#include "rankslam/slam/registration_support.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <vector>

namespace rankslam::slam {
namespace {

// Points on the plane z = 2 m, and as many again `lift_m` in front of it.
std::vector<Eigen::Vector3f> slab(float lift_m) {
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j) {
      points.emplace_back(-0.5F + 0.1F * static_cast<float>(i), -0.5F + 0.1F * static_cast<float>(j), 2.0F);
      points.emplace_back(-0.45F + 0.1F * static_cast<float>(i), -0.45F + 0.1F * static_cast<float>(j), 2.0F - lift_m);
    }
  }
  return points;
}

TEST(RegistrationSupport, ThicknessIsHowFarTheInliersLeaveTheirPlane) {
  const Eigen::Isometry3d identity = Eigen::Isometry3d::Identity();
  for (const float lift_m : {0.0F, 0.2F}) {
    const std::vector<Eigen::Vector3f> points = slab(lift_m);
    const std::vector<double> sigma(points.size(), 0.01);
    // Half the points on each sheet: the standard deviation across them is half the gap (less a
    // little, as the sheets' staggered grids tilt the best plane).
    EXPECT_NEAR(inlier_thickness_m(identity, points, points, sigma), 0.5 * static_cast<double>(lift_m), 2e-3) << lift_m;
  }
  // Outliers (the second sheet's targets far off) do not count: the inliers lie on one plane.
  std::vector<Eigen::Vector3f> source = slab(0.2F);
  std::vector<Eigen::Vector3f> target = source;
  for (std::size_t i = 1; i < target.size(); i += 2) target[i].x() += 1.0F;
  const std::vector<double> sigma(source.size(), 0.01);
  EXPECT_NEAR(inlier_thickness_m(identity, source, target, sigma), 0.0, 1e-4);
  EXPECT_EQ(inlier_thickness_m(identity, {source.data(), 3}, {target.data(), 3}, {sigma.data(), 3}), 0.0);
}

TEST(RegistrationSupport, CorrespondenceInformationIsTheLeastSquaresFitsOnTheInliers) {
  const std::vector<Eigen::Vector3f> points = slab(0.2F);
  const std::vector<double> sigma(points.size(), 0.02);
  const Matrix6d information =
      correspondence_information(Eigen::Isometry3d::Identity(), points, points, sigma);
  // Every point fixes all three translations: n / σ² each.
  const double per_axis = static_cast<double>(points.size()) / (0.02 * 0.02);
  EXPECT_NEAR(information(3, 3), per_axis, 1e-6 * per_axis);
  EXPECT_NEAR(information(4, 4), per_axis, 1e-6 * per_axis);
  EXPECT_NEAR(information(5, 5), per_axis, 1e-6 * per_axis);
  EXPECT_LT((information - information.transpose()).norm(), 1e-6 * per_axis);
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(information);
  EXPECT_GT(eigen.eigenvalues()(0), 0.0);
  // Wrong targets carry none.
  std::vector<Eigen::Vector3f> far = points;
  for (Eigen::Vector3f& p : far) p.z() += 1.0F;
  EXPECT_EQ(correspondence_information(Eigen::Isometry3d::Identity(), points, far, sigma).norm(), 0.0);
}

TEST(RegistrationSupport, SurfaceInformationLeavesFreeWhatTheSurfacesDoNotFix) {
  // A corridor seen along its axis z: two side walls and a floor, no end wall.
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;
  for (float z = 1.0F; z <= 4.0F; z += 0.1F) {
    for (float s = -0.5F; s <= 0.5F; s += 0.1F) {
      points.emplace_back(-0.8F, s, z);
      normals.emplace_back(1.0F, 0.0F, 0.0F);
      points.emplace_back(0.8F, s, z);
      normals.emplace_back(-1.0F, 0.0F, 0.0F);
      points.emplace_back(s, 0.5F, z);
      normals.emplace_back(0.0F, -1.0F, 0.0F);
    }
  }
  const Matrix6d information = surface_information(points, normals);
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(information);
  // Travel along the axis is the one free direction.
  EXPECT_NEAR(eigen.eigenvalues()(0), 0.0, 1e-9);
  EXPECT_GT(eigen.eigenvalues()(1), 1e-2);
  EXPECT_NEAR(std::abs(eigen.eigenvectors().col(0)(5)), 1.0, 1e-6);
  EXPECT_EQ(surface_information({}, {}).norm(), 0.0);
}

}  // namespace
}  // namespace rankslam::slam
