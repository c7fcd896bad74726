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
  EXPECT_LT((mapped - lie::adjoint(T) * xi).norm(), 1e-7) << mapped.transpose();
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

// The corridor robot's mounting: camera 15 cm ahead of the base's axis, 50 cm up, looking forward.
Eigen::Isometry3d corridor_mount() {
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  T_base_cam.linear() = Eigen::Quaterniond(0.5, -0.5, 0.5, -0.5).toRotationMatrix();  // optical → base axes
  T_base_cam.translation() = Eigen::Vector3d(0.15, 0.0, 0.5);
  return T_base_cam;
}

// Information on ξ (right of M) stated as step_prior_information's diagonal gives the same ε
// information: the general conversion and the diagonal one agree.
TEST(RegistrationSupport, PriorInformationOnTheTargetMatchesTheStepPriorsConversion) {
  Eigen::Isometry3d M = turn_about({0.2, 1.0, -0.1}, 12.0);
  M.translation() = Eigen::Vector3d(0.05, -0.02, 0.2);
  const Eigen::Matrix<double, 6, 1> strength = one_degree_one_centimetre();
  const Matrix6d expected = step_prior_information(M, Eigen::Isometry3d::Identity(), strength);
  const Matrix6d converted = prior_information_on_target(M, strength.asDiagonal());
  EXPECT_LT((converted - expected).norm(), 1e-6 * expected.norm());
}

// A base that rolls forward 1 cm and turns 2° keeps that step; the slide, lift and tilt a
// registration may add are not a differential drive's and go, whatever the camera's mounting.
TEST(RegistrationSupport, DrivableStepKeepsForwardTravelAndTurnOnly) {
  const Eigen::Isometry3d T_base_cam = corridor_mount();
  Eigen::Isometry3d drive = turn_about(Eigen::Vector3d::UnitZ(), 2.0);
  drive.translation() = Eigen::Vector3d(0.01, 0.0, 0.0);
  const Eigen::Isometry3d step_cam = T_base_cam.inverse() * drive * T_base_cam;
  const Eigen::Isometry3d kept = drivable_step(step_cam, T_base_cam);
  EXPECT_LT((kept.matrix() - step_cam.matrix()).norm(), 1e-12);

  Eigen::Isometry3d disturbed = drive * turn_about(Eigen::Vector3d::UnitX(), 1.5) * turn_about(Eigen::Vector3d::UnitY(), -0.7);
  disturbed.translation() += Eigen::Vector3d(0.0, 0.004, -0.003);
  const Eigen::Isometry3d base_step =
      T_base_cam * drivable_step(T_base_cam.inverse() * disturbed * T_base_cam, T_base_cam) * T_base_cam.inverse();
  EXPECT_NEAR(base_step.translation().x(), 0.01, 1e-12);
  EXPECT_NEAR(base_step.translation().y(), 0.0, 1e-12);
  EXPECT_NEAR(base_step.translation().z(), 0.0, 1e-12);
  const Eigen::Matrix3d R = base_step.rotation();
  EXPECT_NEAR(R(2, 2), 1.0, 1e-12);  // the vertical stays vertical
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)) * 180.0 / M_PI, 2.0, 0.05);
}

// ξ = (rotation vector, translation) of T_measured⁻¹·T_actual, the graph's edge error, and its
// cost under `information`.
double edge_cost(const Eigen::Isometry3d& T_measured, const Eigen::Isometry3d& T_actual, const Matrix6d& information) {
  const Eigen::Isometry3d off = T_measured.inverse() * T_actual;
  const Eigen::AngleAxisd rotation(off.rotation());
  Eigen::Matrix<double, 6, 1> xi;
  xi << rotation.angle() * rotation.axis(), off.translation();
  return xi.dot(information * xi);
}

// Between two key-frames a differential-drive base keeps its height, roll and pitch: the
// constraint's measurement drops the lift and tilt a registration adds and keeps the travel and
// turn, a lift or tilt of one σ (in the base frame, whatever the mounting) costs 1, and the
// travel and heading cost next to nothing.
TEST(RegistrationSupport, PlanarConstraintHoldsTheBasesHeightAndTiltOnly) {
  const Eigen::Isometry3d T_base_cam = corridor_mount();
  Eigen::Isometry3d drive = turn_about(Eigen::Vector3d::UnitZ(), 10.0);
  drive.translation() = Eigen::Vector3d(0.25, 0.02, 0.0);
  Eigen::Isometry3d registered = drive * turn_about(Eigen::Vector3d::UnitX(), 1.0) * turn_about(Eigen::Vector3d::UnitY(), -0.5);
  registered.translation().z() = 0.03;
  const double height_sigma_m = 0.005;
  const double tilt_sigma_rad = 0.2 * M_PI / 180.0;
  const PlanarConstraint constraint =
      planar_constraint(T_base_cam.inverse() * registered * T_base_cam, T_base_cam, height_sigma_m, tilt_sigma_rad);

  const Eigen::Isometry3d measured_base = T_base_cam * constraint.T_from_to * T_base_cam.inverse();
  EXPECT_NEAR(measured_base.translation().x(), 0.25, 1e-12);
  EXPECT_NEAR(measured_base.translation().y(), 0.02, 1e-12);
  EXPECT_NEAR(measured_base.translation().z(), 0.0, 1e-12);
  const Eigen::Matrix3d R = measured_base.rotation();
  EXPECT_NEAR(R(2, 2), 1.0, 1e-12);
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)) * 180.0 / M_PI, 10.0, 0.02);
  EXPECT_LT((constraint.information - constraint.information.transpose()).norm(), 1e-9 * constraint.information.norm());

  // A deviation D of the base at the later key-frame moves the camera motion to T·T_cam_base·D·T_base_cam.
  const auto deviated = [&](const Eigen::Isometry3d& base_deviation) {
    return Eigen::Isometry3d(constraint.T_from_to * T_base_cam.inverse() * base_deviation * T_base_cam);
  };
  Eigen::Isometry3d lift = Eigen::Isometry3d::Identity();
  lift.translation().z() = height_sigma_m;
  EXPECT_NEAR(edge_cost(constraint.T_from_to, deviated(lift), constraint.information), 1.0, 1e-9);
  for (const Eigen::Vector3d& axis : {Eigen::Vector3d(Eigen::Vector3d::UnitX()), Eigen::Vector3d(Eigen::Vector3d::UnitY())}) {
    const Eigen::Isometry3d tilt = turn_about(axis, tilt_sigma_rad * 180.0 / M_PI);
    EXPECT_NEAR(edge_cost(constraint.T_from_to, deviated(tilt), constraint.information), 1.0, 0.01) << axis.transpose();
  }
  Eigen::Isometry3d travel = Eigen::Isometry3d::Identity();
  travel.translation() = Eigen::Vector3d(0.1, 0.1, 0.0);
  EXPECT_LT(edge_cost(constraint.T_from_to, deviated(travel), constraint.information), 1e-3);
  EXPECT_LT(edge_cost(constraint.T_from_to, deviated(turn_about(Eigen::Vector3d::UnitZ(), 1.0)), constraint.information),
            1e-3);
  // Invertible, so the graph can compose it through covariances.
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6d>(constraint.information).eigenvalues().minCoeff(), 0.0);
}

// Two beliefs on a motion meet where their information weighs them: equal information halfway,
// and a direction only one of them informs follows that one.
TEST(RegistrationSupport, CombinedBeliefsMeetWhereTheirInformationWeighsThem) {
  MotionBelief prior;
  prior.information = Matrix6d::Identity() * 1e4;
  MotionBelief measured;
  measured.mean.translation() = Eigen::Vector3d(0.02, 0.0, 0.04);
  measured.information = Matrix6d::Identity() * 1e4;
  MotionBelief both = combine(prior, measured);
  EXPECT_NEAR(both.mean.translation().x(), 0.01, 1e-9);
  EXPECT_NEAR(both.mean.translation().z(), 0.02, 1e-9);
  EXPECT_LT((both.information - Matrix6d::Identity() * 2e4).norm(), 1e-9);

  // The measurement informs the travel (z) alone, 100 times more than the prior: z follows it,
  // x stays with the prior.
  measured.information.setZero();
  measured.information(5, 5) = 1e6;
  both = combine(prior, measured);
  EXPECT_NEAR(both.mean.translation().x(), 0.0, 1e-9);
  EXPECT_NEAR(both.mean.translation().z(), 0.04 * 100.0 / 101.0, 1e-9);
}

// n points of noise σ spread ±d about the camera's axis at depth z fix the turn about that axis
// to σ / (d·√n)-ish; one point in front leaves it free.
TEST(RegistrationSupport, RotationSigmaIsTheLeastFixedTurnOfAnInformation) {
  std::vector<Eigen::Vector3f> points;
  for (const float x : {-0.5F, 0.5F}) {
    for (const float y : {-0.5F, 0.5F}) points.emplace_back(x, y, 2.0F);
  }
  const std::vector<double> sigma(points.size(), 0.01);
  const Matrix6d information = correspondence_information(Eigen::Isometry3d::Identity(), points, points, sigma);
  // About the optical axis each point sits 0.71 m out: σ_rot = 0.01 / (0.71·√4) = 7.1 mrad; the
  // turns about x and y trade with translation over the 2 m depth and are less fixed.
  const double about_axis = 0.01 / (std::sqrt(0.5) * 2.0);
  EXPECT_GT(rotation_sigma_rad(information), about_axis);
  Matrix6d translations_known = information;
  translations_known.bottomRightCorner<3, 3>() += Eigen::Matrix3d::Identity() * 1e12;
  EXPECT_NEAR(rotation_sigma_rad(translations_known), 0.01 / (std::sqrt(0.5) * 2.0), 1e-6);
  const std::vector<Eigen::Vector3f> one{{0.0F, 0.0F, 2.0F}};
  EXPECT_TRUE(std::isinf(rotation_sigma_rad(
      correspondence_information(Eigen::Isometry3d::Identity(), one, one, std::vector<double>{0.01}))));
}

// A floor seen alone fixes height, roll and pitch but leaves travel, sideways and the turn free:
// against a feature estimate that fixes everything, its least ratio is 0; add walls in front and
// to the sides and every direction is fixed.
TEST(RegistrationSupport, LeastInformationRatioIsWhatTheMeasurementLeavesToTheReference) {
  const Matrix6d reference = Matrix6d::Identity() * 100.0;
  Matrix6d measured = Matrix6d::Identity() * 400.0;
  EXPECT_NEAR(least_information_ratio(measured, reference), 4.0, 1e-9);
  measured(2, 2) = 25.0;
  EXPECT_NEAR(least_information_ratio(measured, reference), 0.25, 1e-9);

  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;
  for (float x = -1.0F; x <= 1.0F; x += 0.25F) {
    for (float z = 1.0F; z <= 3.0F; z += 0.25F) {
      points.emplace_back(x, 0.8F, z);  // floor below the camera (y down)
      normals.emplace_back(0.0F, -1.0F, 0.0F);
    }
  }
  EXPECT_LT(least_information_ratio(surface_information(points, normals), Matrix6d::Identity() * 1e-3), 1e-9);
  for (float y = -0.8F; y <= 0.8F; y += 0.2F) {
    for (float t = -1.0F; t <= 1.0F; t += 0.25F) {
      points.emplace_back(t, y, 3.0F);  // wall ahead
      normals.emplace_back(0.0F, 0.0F, -1.0F);
      points.emplace_back(-1.2F, y, 2.0F + t);  // side walls
      normals.emplace_back(1.0F, 0.0F, 0.0F);
      points.emplace_back(1.2F, y, 2.0F + t);
      normals.emplace_back(-1.0F, 0.0F, 0.0F);
    }
  }
  EXPECT_GT(least_information_ratio(surface_information(points, normals), Matrix6d::Identity() * 1e-3), 1.0);
  Matrix6d not_a_reference = Matrix6d::Identity();
  not_a_reference(4, 4) = 0.0;
  EXPECT_EQ(least_information_ratio(measured, not_a_reference), 0.0);
}

}  // namespace
}  // namespace rankslam::slam
