// Closed-form rigid solver (weighted Umeyama), its degeneracy checks, the rigid model, the
// Kinect correspondence sigmas and the motion gate.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/robust/rigid.hpp"
#include "synthetic_correspondences.hpp"

namespace rankslam::robust {
namespace {

Eigen::Isometry3d make_motion(double angle_rad, const Eigen::Vector3d& axis,
                              const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

Eigen::Matrix3Xd random_points(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> z(0.5, 4.0);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) p.col(i) = Eigen::Vector3d(u(rng), u(rng), z(rng));
  return p;
}

void expect_identity_and_finite(const Eigen::Isometry3d& T) {
  EXPECT_TRUE(T.matrix().allFinite());
  EXPECT_TRUE(T.matrix().isIdentity(0.0));
}

TEST(FitRigid, RecoversExactTransform) {
  const Eigen::Matrix3Xd src = random_points(50, 1);
  const Eigen::Isometry3d truth = make_motion(0.7, {1, 2, 3}, {0.3, -0.2, 1.5});
  const Eigen::Matrix3Xd dst = truth * src;
  Eigen::Isometry3d T;
  ASSERT_EQ(fit_rigid(src, dst, {}, T), RigidFitStatus::kOk);
  EXPECT_LT(translation_difference_m(T, truth), 1e-12);
  EXPECT_LT(rotation_difference_rad(T, truth), 1e-12);
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
}

TEST(FitRigid, RecoversExactTransformFromThreePointsAndLargeRotation) {
  const Eigen::Matrix3Xd src = random_points(3, 2);
  const Eigen::Isometry3d truth = make_motion(3.0, {-1, 0.2, 0.4}, {2.0, 1.0, -3.0});
  const Eigen::Matrix3Xd dst = truth * src;
  Eigen::Isometry3d T;
  ASSERT_EQ(fit_rigid(src, dst, {}, T), RigidFitStatus::kOk);
  EXPECT_LT(translation_difference_m(T, truth), 1e-10);
  EXPECT_LT(rotation_difference_rad(T, truth), 1e-10);
}

TEST(FitRigid, PlanarPointsGiveARotationNotAReflection) {
  // Coplanar points leave the smallest singular value at zero: the sign of the third axis is
  // free, and only the correction keeps det(R) = +1.
  Eigen::Matrix3Xd src = random_points(20, 3);
  src.row(2).setConstant(2.0);
  const Eigen::Isometry3d truth = make_motion(0.4, {0.3, 1, 0}, {0.1, 0.0, 0.2});
  const Eigen::Matrix3Xd dst = truth * src;
  Eigen::Isometry3d T;
  ASSERT_EQ(fit_rigid(src, dst, {}, T), RigidFitStatus::kOk);
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  EXPECT_LT(rotation_difference_rad(T, truth), 1e-10);
  EXPECT_LT(translation_difference_m(T, truth), 1e-10);
}

TEST(FitRigid, MirroredTargetStillYieldsAProperRotation) {
  const Eigen::Matrix3Xd src = random_points(30, 4);
  Eigen::Matrix3Xd dst = src;
  dst.row(0) *= -1.0;  // a reflection: no rotation fits exactly
  Eigen::Isometry3d T;
  ASSERT_EQ(fit_rigid(src, dst, {}, T), RigidFitStatus::kOk);
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  EXPECT_TRUE((T.linear().transpose() * T.linear()).isIdentity(1e-12));
}

TEST(FitRigid, EqualWeightsEqualUnweighted) {
  testing::SceneConfig config;
  config.points = 200;
  const testing::Scene scene = testing::make_scene(config);  // noisy, so the fit is not exact
  Eigen::Isometry3d unweighted;
  Eigen::Isometry3d weighted;
  const std::vector<double> weights(200, 2.7);
  ASSERT_EQ(fit_rigid(scene.src, scene.dst, {}, unweighted), RigidFitStatus::kOk);
  ASSERT_EQ(fit_rigid(scene.src, scene.dst, weights, weighted), RigidFitStatus::kOk);
  EXPECT_TRUE(weighted.matrix().isApprox(unweighted.matrix(), 1e-12));
  EXPECT_GT(translation_difference_m(unweighted, scene.T_t_s), 0.0);
}

TEST(FitRigid, WeightedRecoversExactTransform) {
  const Eigen::Matrix3Xd src = random_points(40, 5);
  const Eigen::Isometry3d truth = make_motion(-0.3, {0, 1, 0.1}, {-0.5, 0.05, 0.2});
  const Eigen::Matrix3Xd dst = truth * src;
  std::vector<double> weights(40);
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> w(0.01, 10.0);
  for (double& v : weights) v = w(rng);
  Eigen::Isometry3d T;
  ASSERT_EQ(fit_rigid(src, dst, weights, T), RigidFitStatus::kOk);
  EXPECT_LT(translation_difference_m(T, truth), 1e-12);
  EXPECT_LT(rotation_difference_rad(T, truth), 1e-12);
}

TEST(FitRigid, ZeroWeightsExcludeCorruptedPoints) {
  const Eigen::Matrix3Xd src = random_points(40, 7);
  const Eigen::Isometry3d truth = make_motion(0.2, {1, 1, 0}, {0.1, 0.2, 0.3});
  Eigen::Matrix3Xd dst = truth * src;
  std::vector<double> weights(40, 1.0);
  for (int i = 0; i < 10; ++i) {
    dst.col(i) += Eigen::Vector3d(0.5, -0.3, 0.2);
    weights[static_cast<std::size_t>(i)] = 0.0;
  }
  Eigen::Isometry3d weighted;
  Eigen::Isometry3d unweighted;
  ASSERT_EQ(fit_rigid(src, dst, weights, weighted), RigidFitStatus::kOk);
  ASSERT_EQ(fit_rigid(src, dst, {}, unweighted), RigidFitStatus::kOk);
  EXPECT_LT(translation_difference_m(weighted, truth), 1e-12);
  EXPECT_GT(translation_difference_m(unweighted, truth), 0.05);
}

TEST(FitRigid, DegenerateInputsReturnStatusAndIdentity) {
  Eigen::Isometry3d T;
  // Fewer than three correspondences.
  const Eigen::Matrix3Xd two = random_points(2, 8);
  EXPECT_EQ(fit_rigid(two, two, {}, T), RigidFitStatus::kTooFewPoints);
  expect_identity_and_finite(T);
  // All points coincident.
  const Eigen::Matrix3Xd same = Eigen::Vector3d(0.1, 0.2, 1.0).replicate(1, 10);
  EXPECT_EQ(fit_rigid(same, same, {}, T), RigidFitStatus::kCoincident);
  expect_identity_and_finite(T);
  // Collinear: rotation about the line is undetermined.
  Eigen::Matrix3Xd line(3, 10);
  for (int i = 0; i < 10; ++i) line.col(i) = Eigen::Vector3d(0.1, 0.2, 1.0) * (1.0 + 0.3 * i);
  EXPECT_EQ(fit_rigid(line, line, {}, T), RigidFitStatus::kCollinear);
  expect_identity_and_finite(T);
  // Collinear target only.
  const Eigen::Matrix3Xd spread = random_points(10, 9);
  EXPECT_EQ(fit_rigid(spread, line, {}, T), RigidFitStatus::kCollinear);
  // Zero total weight.
  EXPECT_EQ(fit_rigid(spread, spread, std::vector<double>(10, 0.0), T),
            RigidFitStatus::kZeroWeight);
  expect_identity_and_finite(T);
  // Non-finite input, negative weight, size mismatch.
  Eigen::Matrix3Xd nan_points = spread;
  nan_points(1, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(fit_rigid(nan_points, spread, {}, T), RigidFitStatus::kNonFinite);
  expect_identity_and_finite(T);
  std::vector<double> negative(10, 1.0);
  negative[4] = -1.0;
  EXPECT_EQ(fit_rigid(spread, spread, negative, T), RigidFitStatus::kNonFinite);
  EXPECT_EQ(fit_rigid(spread, random_points(9, 1), {}, T), RigidFitStatus::kTooFewPoints);
}

// A minimal sample is fitted in closed form (the triangles' planes and a 2D rotation); it must
// be the Umeyama fit of fit_rigid: matched triangles with noise, unrelated triangles (a wrong
// match) and mirror images, which a rotation fits by turning the triangle over.
TEST(RigidModel, MinimalSampleFitIsTheUmeyamaFit) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> angle(-3.0, 3.0);
  RigidModel model(3);
  std::array<int, 3> fitted_by_kind{};
  for (int trial = 0; trial < 3000; ++trial) {
    const Eigen::Matrix3Xd src = random_points(3, 100 + static_cast<std::uint64_t>(trial));
    Eigen::Matrix3Xd dst(3, 3);
    const int kind = trial % 3;
    if (kind == 2) {
      dst = random_points(3, 900000 + static_cast<std::uint64_t>(trial));  // unrelated points
    } else {
      const Eigen::Isometry3d T = make_motion(angle(rng), Eigen::Vector3d(angle(rng), angle(rng), angle(rng)),
                                              Eigen::Vector3d(angle(rng), angle(rng), angle(rng)));
      dst = T * src;
      if (kind == 1) dst.row(0) = -dst.row(0);  // a mirror image
      for (int i = 0; i < 3; ++i) dst.col(i) += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    }
    ASSERT_EQ(model.set_correspondences(src, dst), RobustStatus::kOk);
    if (model.sample_degenerate(std::vector<int>{0, 1, 2})) continue;
    Eigen::Isometry3d closed_form;
    ASSERT_TRUE(model.fit_sample(std::vector<int>{0, 1, 2}, closed_form)) << "trial " << trial;
    Eigen::Isometry3d umeyama;
    ASSERT_EQ(fit_rigid(src, dst, {}, umeyama), RigidFitStatus::kOk) << "trial " << trial;
    EXPECT_NEAR(closed_form.linear().determinant(), 1.0, 1e-12) << "trial " << trial;
    EXPECT_TRUE(closed_form.matrix().isApprox(umeyama.matrix(), 1e-9))
        << "trial " << trial << "\nclosed form\n" << closed_form.matrix() << "\nUmeyama\n" << umeyama.matrix();
    ++fitted_by_kind[static_cast<std::size_t>(kind)];
  }
  for (const int fitted : fitted_by_kind) EXPECT_GT(fitted, 900);  // few triples were degenerate
}

TEST(CheckMinimalSample, RejectsCoincidentAndCollinearTriples) {
  const RigidSolverConfig config;
  const Eigen::Vector3d a(0, 0, 1);
  EXPECT_EQ(check_minimal_sample(a, {1, 0, 1}, {0, 1, 1}, config), RigidFitStatus::kOk);
  EXPECT_EQ(check_minimal_sample(a, a + Eigen::Vector3d(1e-4, 0, 0), {0, 1, 1}, config),
            RigidFitStatus::kCoincident);
  EXPECT_EQ(check_minimal_sample(a, {1, 0, 1}, {2, 0, 1}, config), RigidFitStatus::kCollinear);
  EXPECT_EQ(check_minimal_sample(a, {1, 0, 1}, {2, 0.001, 1}, config),
            RigidFitStatus::kCollinear);  // sliver: aspect 2·area / longest² = 2.5e-4
}

TEST(RigidModel, RejectsBadInputAndKeepsCapacity) {
  RigidModel model(10);
  const Eigen::Matrix3Xd points = random_points(11, 10);
  EXPECT_EQ(model.set_correspondences(points, points), RobustStatus::kCapacityExceeded);
  EXPECT_EQ(model.size(), 0);
  EXPECT_EQ(model.set_correspondences(points.leftCols(5), points.leftCols(4)),
            RobustStatus::kInvalidInput);
  Eigen::Matrix3Xd nan_points = points.leftCols(5);
  nan_points(0, 0) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(model.set_correspondences(nan_points, points.leftCols(5)),
            RobustStatus::kInvalidInput);
  EXPECT_EQ(model.size(), 0);
  const std::vector<double> bad_weights{1.0, 1.0, -0.5, 1.0, 1.0};
  EXPECT_EQ(model.set_correspondences(points.leftCols(5), points.leftCols(5), bad_weights),
            RobustStatus::kInvalidInput);
  EXPECT_EQ(model.set_correspondences(points.leftCols(5), points.leftCols(5)), RobustStatus::kOk);
  EXPECT_EQ(model.size(), 5);
}

TEST(RigidModel, ResidualsMatchDefinition) {
  const Eigen::Matrix3Xd src = random_points(300, 11);  // more than one evaluation block
  const Eigen::Matrix3Xd dst = random_points(300, 12);
  RigidModel model(300);
  ASSERT_EQ(model.set_correspondences(src, dst), RobustStatus::kOk);
  const Eigen::Isometry3d T = make_motion(0.5, {1, -1, 2}, {0.2, 0.1, -0.4});
  std::vector<double> r2(300);
  model.squared_residuals(T, 0, 300, r2.data());
  for (int i = 0; i < 300; ++i) {
    EXPECT_NEAR(r2[static_cast<std::size_t>(i)], (T * src.col(i) - dst.col(i)).squaredNorm(),
                1e-12);
  }
  // A sub-range writes exactly that range.
  std::vector<double> part(7);
  model.squared_residuals(T, 130, 7, part.data());
  for (int i = 0; i < 7; ++i) {
    EXPECT_DOUBLE_EQ(part[static_cast<std::size_t>(i)], r2[static_cast<std::size_t>(130 + i)]);
  }
}

// The one-pass scores are the selection scores scaled by the inverse variances, value for
// value (the hypothesis ranking must not depend on the CPU's vector width), and the count below
// the bound is exact; sub-ranges of every length exercise the 8-wide body and its tail.
TEST(RigidModel, ScaledSelectionScoresAreTheScaledSelectionScores) {
  constexpr int kPoints = 301;
  const Eigen::Matrix3Xd src = random_points(kPoints, 21);
  const Eigen::Matrix3Xd dst = random_points(kPoints, 22);
  RigidModel model(kPoints);
  ASSERT_EQ(model.set_correspondences(src, dst), RobustStatus::kOk);
  const Eigen::Isometry3d T = make_motion(0.3, {0.2, 1, -0.5}, {0.1, -0.3, 0.2});
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> inverse_variance(1e2, 1e6);
  std::vector<double> inverse_variances(kPoints);
  for (double& v : inverse_variances) v = inverse_variance(rng);
  std::vector<double> reference(kPoints);
  std::vector<double> scores(kPoints);
  for (const bool scaled : {false, true}) {
    for (const auto& [begin, count] : {std::pair{0, kPoints}, std::pair{5, 8}, std::pair{17, 7},
                                       std::pair{40, 129}, std::pair{300, 1}}) {
      model.selection_scores(T, begin, count, reference.data());
      const double* factors = scaled ? inverse_variances.data() + begin : nullptr;
      if (scaled) {
        for (int i = 0; i < count; ++i) reference[static_cast<std::size_t>(i)] *= factors[i];
      }
      std::vector<double> sorted(reference.begin(), reference.begin() + count);
      std::sort(sorted.begin(), sorted.end());
      const double bound = sorted[sorted.size() / 2];  // about half below, ties included
      const int expected_below = static_cast<int>(
          std::count_if(reference.begin(), reference.begin() + count, [&](double v) { return v < bound; }));
      const int below = model.scaled_selection_scores(T, begin, count, factors, bound, scores.data());
      EXPECT_EQ(below, expected_below) << "begin " << begin << ", count " << count;
      for (int i = 0; i < count; ++i) {
        ASSERT_EQ(scores[static_cast<std::size_t>(i)], reference[static_cast<std::size_t>(i)])
            << "point " << begin + i << (scaled ? ", scaled" : "");
      }
    }
  }
}

TEST(RigidModel, ModelWeightsWeightTheRefit) {
  // The fused registration's per-kind weights live in the model: zero-weight points must not
  // pull the refit even when they are in the index list.
  testing::SceneConfig config;
  config.points = 100;
  config.second_motion_fraction = 0.3;
  config.axial_coefficient_per_m = 0.0;
  config.lateral_sigma_m = 0.0;
  const testing::Scene scene = testing::make_scene(config);
  std::vector<double> weights(100);
  std::vector<int> all(100);
  for (int i = 0; i < 100; ++i) {
    all[static_cast<std::size_t>(i)] = i;
    weights[static_cast<std::size_t>(i)] =
        scene.kind[static_cast<std::size_t>(i)] == testing::PointKind::kInlier ? 1.0 : 0.0;
  }
  RigidModel model(100);
  ASSERT_EQ(model.set_correspondences(scene.src, scene.dst, weights), RobustStatus::kOk);
  Eigen::Isometry3d T;
  ASSERT_TRUE(model.fit_inliers(all, nullptr, T));
  EXPECT_LT(translation_difference_m(T, scene.T_t_s), 1e-10);
  EXPECT_LT(rotation_difference_rad(T, scene.T_t_s), 1e-10);
}

TEST(CorrespondenceSigmas, FollowsTheKinectModel) {
  Eigen::Matrix3Xd src(3, 2);
  Eigen::Matrix3Xd dst(3, 2);
  src << 0.0, 0.5, 0.0, 0.0, 1.0, 4.0;
  dst << 0.0, 0.0, 0.0, 0.0, 2.0, 4.0;
  std::vector<double> sigma(2);
  const DepthNoiseModel noise;
  ASSERT_EQ(correspondence_sigmas_m(src, dst, noise, sigma), RobustStatus::kOk);
  const double a = noise.axial_coefficient_per_m;
  const double lat2 = 4.0 * noise.lateral_sigma_m * noise.lateral_sigma_m;
  EXPECT_NEAR(sigma[0], std::sqrt(a * a * (1.0 + 16.0) + lat2), 1e-15);
  EXPECT_NEAR(sigma[1], std::sqrt(a * a * (256.0 + 256.0) + lat2), 1e-15);
  src(2, 1) = 0.0;
  EXPECT_EQ(correspondence_sigmas_m(src, dst, noise, sigma), RobustStatus::kInvalidInput);
  std::vector<double> short_out(1);
  EXPECT_EQ(correspondence_sigmas_m(src, dst, noise, short_out), RobustStatus::kInvalidInput);
}

TEST(RigidMotionGate, AcceptsOnlyNearThePrediction) {
  RigidMotionGate gate;
  gate.T_t_s_predicted = make_motion(0.1, {0, 1, 0}, {0.1, 0, 0});
  gate.max_translation_m = 0.05;
  gate.max_rotation_rad = 0.05;
  EXPECT_TRUE(gate(gate.T_t_s_predicted));
  EXPECT_TRUE(gate(make_motion(0.14, {0, 1, 0}, {0.14, 0, 0})));
  EXPECT_FALSE(gate(make_motion(0.1, {0, 1, 0}, {0.2, 0, 0})));
  EXPECT_FALSE(gate(make_motion(0.2, {0, 1, 0}, {0.1, 0, 0})));
}

TEST(RotationDifference, IsAccurateForTinyAndLargeAngles) {
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  EXPECT_NEAR(rotation_difference_rad(I, make_motion(1e-7, {1, 2, 3}, {0, 0, 0})), 1e-7, 1e-15);
  EXPECT_NEAR(rotation_difference_rad(I, make_motion(3.0, {1, 2, 3}, {0, 0, 0})), 3.0, 1e-12);
  EXPECT_NEAR(rotation_difference_rad(make_motion(1.0, {0, 0, 1}, {0, 0, 0}),
                                      make_motion(1.5, {0, 0, 1}, {0, 0, 0})),
              0.5, 1e-12);
}

}  // namespace
}  // namespace rankslam::robust
