#include "rankslam/slam/registration_support.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
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

// The deviation PlaneIcp's prior is given: ε = log(T·M⁻¹), rotation vector then translation.
Eigen::Matrix<double, 6, 1> icp_prior_deviation(const Eigen::Isometry3d& T, const Eigen::Isometry3d& M) {
  const Eigen::Isometry3d off = T * M.inverse();
  const Eigen::AngleAxisd rotation(off.rotation());
  Eigen::Matrix<double, 6, 1> epsilon;
  epsilon << rotation.angle() * rotation.axis(), off.translation();
  return epsilon;
}

double prior_cost(const Eigen::Isometry3d& T, const Eigen::Isometry3d& M, const Matrix6d& information) {
  const Eigen::Matrix<double, 6, 1> epsilon = icp_prior_deviation(T, M);
  return epsilon.dot(information * epsilon);
}

Eigen::Isometry3d turn_about(const Eigen::Vector3d& axis, double angle_deg) {
  Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
  turn.linear() = Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
  return turn;
}

// 1° and 1 cm per step, as the fused ICP's prior.
Eigen::Matrix<double, 6, 1> one_degree_one_centimetre() {
  const double rad = M_PI / 180.0;
  Eigen::Matrix<double, 6, 1> information;
  information << Eigen::Vector3d::Constant(1.0 / (rad * rad)), Eigen::Vector3d::Constant(1e4);
  return information;
}

TEST(RegistrationSupport, AdjointMapsASmallMotionIntoTheFrameAPoseMapsFrom) {
  Eigen::Isometry3d T = turn_about({0.3, -1.0, 0.2}, 40.0);
  T.translation() = Eigen::Vector3d(0.4, -0.2, 1.5);
  Eigen::Matrix<double, 6, 1> xi;
  xi << 1e-4, -2e-4, 3e-4, 2e-4, 1e-4, -3e-4;
  Eigen::Isometry3d small = turn_about(xi.head<3>(), xi.head<3>().norm() * 180.0 / M_PI);
  small.translation() = xi.tail<3>();
  const Eigen::Matrix<double, 6, 1> mapped = icp_prior_deviation(T * small * T.inverse(), Eigen::Isometry3d::Identity());
  EXPECT_LT((mapped - adjoint(T) * xi).norm(), 1e-7) << mapped.transpose();
}

// Against a target 20 cm behind the prior's pose (a key-frame reference), a turn about the
// camera costs the turn alone; the diagonal put on ε directly charges a translation as well.
TEST(RegistrationSupport, StepPriorChargesATurnAboutTheCameraAsATurnWhereverTheTargetIs) {
  Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
  M.translation() = Eigen::Vector3d(0.0, 0.0, 0.2);
  const Eigen::Isometry3d turned = M * turn_about(Eigen::Vector3d::UnitY(), 1.0);
  const Eigen::Matrix<double, 6, 1> strength = one_degree_one_centimetre();
  const double step_cost =
      prior_cost(turned, M, step_prior_information(M, Eigen::Isometry3d::Identity(), strength));
  EXPECT_NEAR(step_cost, 1.0, 1e-3);  // one sigma of rotation
  const Matrix6d on_epsilon = strength.asDiagonal();
  EXPECT_GT(prior_cost(turned, M, on_epsilon), 1.1);  // 3.5 mm read as translation: 1 + 0.12
}

// A wheeled base turning in place swings a camera mounted ahead of its axis: at rest in the base
// frame that costs the turn alone, held in the camera frame it costs the swing as well; a
// camera that slides forward costs the same in both.
TEST(RegistrationSupport, StepPriorInTheBaseFrameLetsTheCameraSwingOnItsMount) {
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  T_base_cam.linear() = Eigen::Quaterniond(0.5, -0.5, 0.5, -0.5).toRotationMatrix();  // optical → base axes
  T_base_cam.translation() = Eigen::Vector3d(0.15, 0.0, 0.5);
  const Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
  const Eigen::Matrix<double, 6, 1> strength = one_degree_one_centimetre();
  const Matrix6d base = step_prior_information(M, T_base_cam, strength);
  const Matrix6d camera = step_prior_information(M, Eigen::Isometry3d::Identity(), strength);
  const Eigen::Isometry3d swing = T_base_cam.inverse() * turn_about(Eigen::Vector3d::UnitZ(), 2.0) * T_base_cam;
  EXPECT_NEAR(swing.translation().norm(), 0.15 * 2.0 * M_PI / 180.0, 1e-4);  // 5.2 mm
  EXPECT_NEAR(prior_cost(swing, M, base), 4.0, 4e-3);
  EXPECT_GT(prior_cost(swing, M, camera), 4.2);
  Eigen::Isometry3d forward = Eigen::Isometry3d::Identity();
  forward.translation() = Eigen::Vector3d(0.0, 0.0, 0.01);
  EXPECT_NEAR(prior_cost(forward, M, base), 1.0, 1e-9);
  EXPECT_NEAR(prior_cost(forward, M, camera), 1.0, 1e-9);
}

}  // namespace
}  // namespace rankslam::slam
