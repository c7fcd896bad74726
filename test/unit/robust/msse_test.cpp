// MSSE: the transition search, and rigid registration on synthetic Kinect-like correspondences
// with uniform and structured outliers, degenerate inputs, reproducibility and the gate.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/rigid.hpp"
#include "synthetic_correspondences.hpp"

namespace rankslam::robust {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;
constexpr int kPoints = 500;

// Unoptimised (debug, sanitizer) builds run MSSE ~1000× slower; they exist to find memory and
// UB errors, so there the scene sweeps are shortened and the 100-scene statistic is skipped.
#ifdef __OPTIMIZE__
constexpr bool kOptimisedBuild = true;
#else
constexpr bool kOptimisedBuild = false;
#endif
constexpr std::uint64_t kSweepScenes = kOptimisedBuild ? 10 : 2;

testing::Scene scene_with(double outlier_fraction, std::uint64_t seed, int points = kPoints,
                          double second_motion_fraction = 0.0) {
  testing::SceneConfig config;
  config.points = points;
  config.outlier_fraction = outlier_fraction;
  config.second_motion_fraction = second_motion_fraction;
  config.seed = seed;
  return testing::make_scene(config);
}

/// Share of the reported inliers that are true inliers, and of the true inliers reported.
struct InlierQuality {
  double precision = 0.0;
  double recall = 0.0;
};

InlierQuality inlier_quality(const testing::Scene& scene, std::span<const int> inliers) {
  int true_positive = 0;
  for (const int i : inliers) {
    true_positive += scene.kind[static_cast<std::size_t>(i)] == testing::PointKind::kInlier;
  }
  int truth = 0;
  for (const testing::PointKind k : scene.kind) truth += k == testing::PointKind::kInlier;
  return {static_cast<double>(true_positive) / static_cast<double>(inliers.size()),
          static_cast<double>(true_positive) / static_cast<double>(truth)};
}

class MsseRigid : public ::testing::Test {
 protected:
  RigidModel model_{kPoints};
  RobustWorkspace workspace_{kPoints};
  std::vector<double> sigmas_ = std::vector<double>(kPoints);

  RobustResult<Eigen::Isometry3d> run(const testing::Scene& scene, const MsseConfig& config,
                                      bool normalise) {
    EXPECT_EQ(model_.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
    std::span<const double> point_sigma;
    if (normalise) {
      EXPECT_EQ(correspondence_sigmas_m(scene.src, scene.dst, DepthNoiseModel{}, sigmas_),
                RobustStatus::kOk);
      point_sigma = std::span<const double>(sigmas_.data(),
                                             static_cast<std::size_t>(scene.src.cols()));
    }
    return estimate_msse(model_, config, workspace_, point_sigma);
  }
};

TEST(MsseTransition, HandComputedExample) {
  // r = 1, 1, 1, 1, 10; k0 = 2, p = 0, T = 2.5: σ² stays 1 while 1 ≤ 2.5, then 10 > 2.5.
  const std::vector<double> r2{1, 1, 1, 1, 100};
  double sigma_sq = 0.0;
  EXPECT_EQ(msse_transition(r2, 2, 0, 2.5, &sigma_sq), 4);
  EXPECT_DOUBLE_EQ(sigma_sq, 1.0);
  // p = 1: σ_j² = j/(j − 1) grows the threshold but 10 still exceeds it.
  EXPECT_EQ(msse_transition(r2, 2, 1, 2.5, &sigma_sq), 4);
  EXPECT_DOUBLE_EQ(sigma_sq, 4.0 / 3.0);
  // A large T takes everything.
  EXPECT_EQ(msse_transition(r2, 2, 0, 20.0, &sigma_sq), 5);
  EXPECT_DOUBLE_EQ(sigma_sq, 104.0 / 5.0);
}

TEST(MsseTransition, SinglePrecisionMatchesDouble) {
  // The float overload (image saliency) segments as the double one on the same values.
  std::vector<double> r2;
  std::vector<float> r2f;
  for (int i = 0; i < 1000; ++i) {
    const double v = i < 800 ? 0.5 + 0.001 * i : 40.0 + i;
    r2.push_back(static_cast<double>(static_cast<float>(v)));
    r2f.push_back(static_cast<float>(v));
  }
  double sd = 0.0;
  double sf = 0.0;
  const int jd = msse_transition(std::span<const double>(r2), 200, 0, 2.5, &sd);
  const int jf = msse_transition(std::span<const float>(r2f), 200, 0, 2.5, &sf);
  EXPECT_EQ(jd, 800);
  EXPECT_EQ(jf, jd);
  EXPECT_DOUBLE_EQ(sf, sd);
}

TEST(MsseTransition, EdgeCases) {
  const std::vector<double> zeros(10, 0.0);
  double sigma_sq = -1.0;
  EXPECT_EQ(msse_transition(zeros, 3, 0, 2.5, &sigma_sq), 10);  // r ≤ T·0 holds for r = 0
  EXPECT_EQ(sigma_sq, 0.0);
  const std::vector<double> step{0, 0, 0, 1e-30};
  EXPECT_EQ(msse_transition(step, 2, 0, 2.5), 3);  // any positive jump over σ = 0 stops
  const std::vector<double> r2{1, 2, 3};
  EXPECT_EQ(msse_transition(r2, 3, 0, 2.5), 3);  // k0 = n
}

TEST(MsseTransition, GaussianScaleIsTheTruncatedFixedPoint) {
  // Pure N(0, σ²) residuals. σ_{k*} is computed from the points kept, so it is a truncated
  // estimate: the stop c (in units of σ) solves c = T·sqrt(g(c)), g(c) = 1 − 2cφ(c)/(2Φ(c) − 1),
  // which for T = 2.5 gives c ≈ 2.34, σ_{k*} ≈ 0.935·σ and k* ≈ 98.1 % of n.
  const double sigma = 0.01;
  std::vector<double> r2(20000);
  Pcg32 rng(1);
  for (double& v : r2) {
    // Box–Muller
    const double u1 = 1.0 - rng.uniform01();
    const double u2 = rng.uniform01();
    const double z = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
    v = (sigma * z) * (sigma * z);
  }
  std::sort(r2.begin(), r2.end());
  double sigma_sq = 0.0;
  const int k_star = msse_transition(r2, 4000, 0, 2.5, &sigma_sq);
  EXPECT_NEAR(k_star / 20000.0, 0.981, 0.004);
  EXPECT_NEAR(std::sqrt(sigma_sq) / sigma, 0.935, 0.015);
}

TEST(MsseFirstOrder, CeilAndFloors) {
  EXPECT_EQ(msse_first_order(0.2, 500, 6, 3), 100);
  EXPECT_EQ(msse_first_order(0.1, 501, 6, 3), 51);
  EXPECT_EQ(msse_first_order(0.1, 30, 6, 3), 7);  // raised to p + 1
  EXPECT_EQ(msse_first_order(0.2, 0, 0, 0), 1);
}

TEST(MsseConfig, ValidateNamesTheField) {
  MsseConfig config;
  EXPECT_TRUE(config.validate().empty());
  config.min_inlier_fraction = 0.0;
  EXPECT_EQ(config.validate(), "min_inlier_fraction");
  config = MsseConfig{};
  config.transition_factor = -1.0;
  EXPECT_EQ(config.validate(), "transition_factor");
  config = MsseConfig{};
  config.hypotheses = 0;
  EXPECT_EQ(config.validate(), "hypotheses");
  config = MsseConfig{};
  config.refine_iterations = -1;
  EXPECT_EQ(config.validate(), "refine_iterations");
}

// The accuracy target, 2 mm and 0.2°, holds with per-point noise normalisation up to 80 %
// uniform outliers (κ = 0.1 < the 20 % inliers; n = 500 as ORB matching gives). Without it the
// unweighted refit is limited by the far points' noise (σ_z ≈ 23 mm at 4 m): even least squares
// on the true inliers alone misses 2 mm then, so plain MSSE is held to 4 mm.
TEST_F(MsseRigid, RecoversTransformUpTo80PercentUniformOutliers) {
  const MsseConfig config;
  for (const double ratio : {0.0, 0.2, 0.4, 0.6, 0.7, 0.8}) {
    for (std::uint64_t seed = 1; seed <= kSweepScenes; ++seed) {
      SCOPED_TRACE(::testing::Message() << "outliers " << ratio << " seed " << seed);
      const testing::Scene scene = scene_with(ratio, seed);
      {
        const auto result = run(scene, config, true);
        ASSERT_TRUE(result.ok());
        EXPECT_TRUE(result.refined);
        const testing::PoseError e = testing::pose_error(result.model, scene.T_t_s);
        EXPECT_LT(e.translation_m, 0.002);
        EXPECT_LT(e.rotation_rad * kDegPerRad, 0.2);
        const InlierQuality q = inlier_quality(scene, result.inliers);
        EXPECT_GT(q.precision, 0.97);
        EXPECT_GT(q.recall, 0.9);
      }
      {
        const auto result = run(scene, config, false);
        ASSERT_TRUE(result.ok());
        const testing::PoseError e = testing::pose_error(result.model, scene.T_t_s);
        EXPECT_LT(e.translation_m, 0.004);
        EXPECT_LT(e.rotation_rad * kDegPerRad, 0.2);
        EXPECT_GT(inlier_quality(scene, result.inliers).precision, 0.97);
      }
    }
  }
}

// At 80 % outliers, P(no all-inlier triple among H = 1000) = (1 − 0.2³)^1000 ≈ 3·10⁻⁴ per call,
// and noisy all-inlier triples can still lose. Measured: 1 miss in these 100 scenes (seed 21
// draws no all-inlier triple at all); allow 2.
TEST_F(MsseRigid, FailureRateAt80PercentOutliers) {
  if (!kOptimisedBuild) {
    GTEST_SKIP() << "100-scene statistic: run it in an optimised build (minutes unoptimised)";
  }
  int misses = 0;
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    const testing::Scene scene = scene_with(0.8, seed);
    const auto result = run(scene, MsseConfig{}, true);
    ASSERT_TRUE(result.ok());
    const testing::PoseError e = testing::pose_error(result.model, scene.T_t_s);
    misses += e.translation_m > 0.002 || e.rotation_rad * kDegPerRad > 0.2 ? 1 : 0;
  }
  EXPECT_LE(misses, 2);
}

// Sharing step 1 among a thread team draws the same samples and keeps the same winner: the
// estimate, its inliers and its counts are those of the serial loop, with and without noise
// normalisation, with a gate that rejects many hypotheses, and with draws left over.
TEST_F(MsseRigid, ATeamGivesTheSerialEstimate) {
  parallel::ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  MsseTeamScratch<Eigen::Isometry3d> scratch;
  scratch.reserve(&team, 1000, RigidModel::kSampleSize, kPoints);
  RobustWorkspace serial_workspace(kPoints);
  RigidMotionGate gate;
  gate.max_translation_m = 0.3;
  gate.max_rotation_rad = 0.3;
  int gated_total = 0;
  for (const double ratio : {0.0, 0.5, 0.8, 0.9}) {
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
      SCOPED_TRACE(::testing::Message() << "outliers " << ratio << " seed " << seed);
      const testing::Scene scene = scene_with(ratio, seed);
      ASSERT_EQ(model_.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
      ASSERT_EQ(correspondence_sigmas_m(scene.src, scene.dst, DepthNoiseModel{}, sigmas_), RobustStatus::kOk);
      const std::span<const double> sigma(sigmas_.data(), static_cast<std::size_t>(scene.src.cols()));
      for (const bool gated : {false, true}) {
        for (const bool normalised : {false, true}) {
          MsseConfig config;
          config.seed = seed * 7919;
          const std::span<const double> point_sigma = normalised ? sigma : std::span<const double>{};
          const auto serial = gated ? estimate_msse(model_, config, serial_workspace, point_sigma, gate)
                                    : estimate_msse(model_, config, serial_workspace, point_sigma);
          const auto shared = gated ? estimate_msse(model_, config, workspace_, point_sigma, gate, &scratch)
                                    : estimate_msse(model_, config, workspace_, point_sigma,
                                                    AcceptAllHypotheses{}, &scratch);
          ASSERT_EQ(serial.status, shared.status);
          EXPECT_EQ(serial.hypotheses_evaluated, shared.hypotheses_evaluated);
          EXPECT_EQ(serial.degenerate_samples, shared.degenerate_samples);
          EXPECT_EQ(serial.gated_hypotheses, shared.gated_hypotheses);
          gated_total += shared.gated_hypotheses;
          if (!serial.ok()) continue;
          EXPECT_EQ(serial.inlier_count, shared.inlier_count);
          EXPECT_EQ(serial.least_kth_sq_residual, shared.least_kth_sq_residual);
          EXPECT_TRUE(serial.model.matrix() == shared.model.matrix());
          EXPECT_TRUE(std::equal(serial.inliers.begin(), serial.inliers.end(), shared.inliers.begin()));
        }
      }
    }
  }
  EXPECT_GT(gated_total, 1000) << "the gate should have rejected hypotheses";
}

// The bounds a team's threads score under, played in an order a team may take: thread 1 scores
// hypothesis 7 before thread 0 reaches hypothesis 3, which ties it. Hypothesis 3 must still get
// through (the other thread's value bounds inclusively) and win on its index; a later tie on the
// same thread must not get through (a thread's own value bounds strictly, as serially).
TEST(MsseTeamLeastKth, BoundsAndMergeKeepTheSerialWinner) {
  detail::TeamLeastKth team;
  double bound = 0.0;
  EXPECT_FALSE(team.bound(0, bound));
  EXPECT_FALSE(team.bound(1, bound));
  team.record(1, 7, 0.5);
  ASSERT_TRUE(team.bound(0, bound));
  EXPECT_GT(bound, 0.5) << "another thread's tie must get through";
  EXPECT_EQ(bound, std::nextafter(0.5, 1.0));
  team.record(0, 3, 0.5);
  ASSERT_TRUE(team.bound(0, bound));
  EXPECT_EQ(bound, 0.5) << "a later tie on the same thread must not";
  ASSERT_TRUE(team.bound(1, bound));
  EXPECT_EQ(bound, 0.5);
  double kth = 0.0;
  EXPECT_EQ(team.winner(2, kth), 3);
  EXPECT_EQ(kth, 0.5);
  // A strictly better value anywhere wins and bounds every thread.
  team.record(1, 9, 0.25);
  EXPECT_EQ(team.winner(2, kth), 9);
  EXPECT_EQ(kth, 0.25);
  ASSERT_TRUE(team.bound(0, bound));
  EXPECT_EQ(bound, std::nextafter(0.25, 1.0));
  // Threads past the team's size are not merged.
  team.record(2, 1, 0.125);
  EXPECT_EQ(team.winner(2, kth), 9);
  EXPECT_EQ(team.winner(3, kth), 1);
}

TEST_F(MsseRigid, ScaleAndInliersAreConsistent) {
  const testing::Scene scene = scene_with(0.5, 3);
  const auto result = run(scene, MsseConfig{}, false);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.k0, 50);
  EXPECT_GE(result.inlier_count, result.k0);
  ASSERT_EQ(result.inliers.size(), static_cast<std::size_t>(result.inlier_count));
  ASSERT_EQ(result.ordered.size(), static_cast<std::size_t>(kPoints));
  ASSERT_EQ(result.inlier_mask.size(), static_cast<std::size_t>(kPoints));
  int marked = 0;
  for (const std::uint8_t m : result.inlier_mask) marked += m;
  EXPECT_EQ(marked, result.inlier_count);
  for (const int i : result.inliers) EXPECT_EQ(result.inlier_mask[static_cast<std::size_t>(i)], 1);
  EXPECT_TRUE(std::is_sorted(result.sorted_sq_residuals.begin(), result.sorted_sq_residuals.end()));
  // The transition: the next residual exceeds T·σ (or every point is an inlier).
  if (result.inlier_count < kPoints) {
    const double next = std::sqrt(result.sorted_sq_residuals[static_cast<std::size_t>(
        result.inlier_count)]);
    EXPECT_GT(next, 2.5 * result.scale * 0.99);
  }
  // Scale of the inliers: mm-level for this noise, far below the outliers' metres.
  EXPECT_GT(result.scale, 0.001);
  EXPECT_LT(result.scale, 0.03);
  EXPECT_EQ(result.hypotheses_evaluated, 1000);
}

TEST_F(MsseRigid, ReturnsTheDominantOfTwoMotions) {
  for (std::uint64_t seed = 1; seed <= kSweepScenes; ++seed) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    // 70 % dominant vs 30 % moving object, then 50 % vs 30 % with 20 % uniform outliers.
    for (const double outliers : {0.0, 0.2}) {
      const testing::Scene scene = scene_with(outliers, seed, kPoints, 0.3);
      for (const bool normalise : {false, true}) {
        const auto result = run(scene, MsseConfig{}, normalise);
        ASSERT_TRUE(result.ok());
        const testing::PoseError e = testing::pose_error(result.model, scene.T_t_s);
        EXPECT_LT(e.translation_m, normalise ? 0.002 : 0.004);
        EXPECT_LT(e.rotation_rad * kDegPerRad, 0.2);
        int from_second = 0;
        for (const int i : result.inliers) {
          from_second +=
              scene.kind[static_cast<std::size_t>(i)] == testing::PointKind::kSecondMotion;
        }
        EXPECT_EQ(from_second, 0);
      }
    }
  }
}

TEST_F(MsseRigid, NoOutliersNoiseFreeIsExact) {
  testing::SceneConfig config;
  config.points = 100;
  config.axial_coefficient_per_m = 0.0;
  config.lateral_sigma_m = 0.0;
  const testing::Scene scene = testing::make_scene(config);
  const auto result = run(scene, MsseConfig{}, false);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.inlier_count, 100);
  EXPECT_LT(translation_difference_m(result.model, scene.T_t_s), 1e-9);
  EXPECT_LT(rotation_difference_rad(result.model, scene.T_t_s), 1e-9);
}

TEST_F(MsseRigid, SameSeedSameResultOtherSeedSameAnswer) {
  const testing::Scene scene = scene_with(0.6, 4);
  MsseConfig config;
  const auto first = run(scene, config, false);
  const Eigen::Matrix4d first_model = first.model.matrix();
  const std::vector<int> first_inliers(first.inliers.begin(), first.inliers.end());
  const auto second = run(scene, config, false);
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_TRUE(second.model.matrix() == first_model);  // bitwise
  EXPECT_EQ(std::vector<int>(second.inliers.begin(), second.inliers.end()), first_inliers);
  config.seed = 12345;
  const auto other = run(scene, config, false);
  ASSERT_TRUE(other.ok());
  EXPECT_LT(translation_difference_m(other.model, scene.T_t_s), 0.004);
}

TEST_F(MsseRigid, DegenerateInputsFailWithoutNaN) {
  const auto expect_clean_failure = [](const RobustResult<Eigen::Isometry3d>& result,
                                       RobustStatus status) {
    EXPECT_EQ(result.status, status);
    EXPECT_FALSE(result.ok());
    EXPECT_TRUE(result.model.matrix().allFinite());
    EXPECT_TRUE(result.model.matrix().isIdentity(0.0));
    EXPECT_EQ(result.inlier_count, 0);
    EXPECT_TRUE(result.inliers.empty());
  };
  const MsseConfig config;
  // All points coincident.
  const Eigen::Matrix3Xd same = Eigen::Vector3d(0.1, -0.2, 2.0).replicate(1, 50);
  ASSERT_EQ(model_.set_correspondences(same, same), RobustStatus::kOk);
  expect_clean_failure(estimate_msse(model_, config, workspace_), RobustStatus::kDegenerate);
  // All points on a line.
  Eigen::Matrix3Xd line(3, 50);
  for (int i = 0; i < 50; ++i) line.col(i) = Eigen::Vector3d(0.1, -0.2, 1.0) * (1.0 + 0.05 * i);
  ASSERT_EQ(model_.set_correspondences(line, line), RobustStatus::kOk);
  const auto collinear = estimate_msse(model_, config, workspace_);
  expect_clean_failure(collinear, RobustStatus::kDegenerate);
  EXPECT_EQ(collinear.degenerate_samples, 4000);  // the whole draw budget, then it stops
  // Fewer than 3 points, and fewer than p + 1 = 7 (MSSE's σ needs j > p).
  const testing::Scene scene = scene_with(0.0, 1, 6);
  ASSERT_EQ(model_.set_correspondences(scene.src.leftCols(2), scene.dst.leftCols(2)),
            RobustStatus::kOk);
  expect_clean_failure(estimate_msse(model_, config, workspace_), RobustStatus::kTooFewPoints);
  ASSERT_EQ(model_.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
  expect_clean_failure(estimate_msse(model_, config, workspace_), RobustStatus::kTooFewPoints);
  ASSERT_EQ(model_.set_correspondences(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xd(3, 0)),
            RobustStatus::kOk);
  expect_clean_failure(estimate_msse(model_, config, workspace_), RobustStatus::kTooFewPoints);
}

TEST_F(MsseRigid, RejectsBadConfigSigmasAndCapacity) {
  const testing::Scene scene = scene_with(0.2, 2);
  ASSERT_EQ(model_.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
  MsseConfig config;
  config.min_inlier_fraction = 1.5;
  EXPECT_EQ(estimate_msse(model_, config, workspace_).status, RobustStatus::kInvalidConfig);
  const std::vector<double> short_sigmas(10, 0.01);
  EXPECT_EQ(estimate_msse(model_, MsseConfig{}, workspace_, short_sigmas).status,
            RobustStatus::kInvalidInput);
  std::vector<double> zero_sigma(kPoints, 0.01);
  zero_sigma[7] = 0.0;
  EXPECT_EQ(estimate_msse(model_, MsseConfig{}, workspace_, zero_sigma).status,
            RobustStatus::kInvalidInput);
  RobustWorkspace small(100);
  EXPECT_EQ(estimate_msse(model_, MsseConfig{}, small).status, RobustStatus::kCapacityExceeded);
}

TEST_F(MsseRigid, GateAroundThePredictionKeepsTheAnswer) {
  const testing::Scene scene = scene_with(0.8, 5);
  ASSERT_EQ(model_.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
  RigidMotionGate gate;
  gate.T_t_s_predicted = scene.T_t_s;
  gate.T_t_s_predicted.translation() += Eigen::Vector3d(0.02, -0.01, 0.0);  // odometry error
  gate.max_translation_m = 0.05;
  gate.max_rotation_rad = 0.05;
  const auto gated = estimate_msse(model_, MsseConfig{}, workspace_, {}, gate);
  ASSERT_TRUE(gated.ok());
  EXPECT_GT(gated.gated_hypotheses, 0);
  EXPECT_EQ(gated.hypotheses_evaluated + gated.gated_hypotheses + gated.degenerate_samples,
            4000);  // gated draws are replaced until the draw budget ends
  EXPECT_LT(translation_difference_m(gated.model, scene.T_t_s), 0.004);
  // A prediction far from the truth rejects everything.
  gate.T_t_s_predicted.translation() += Eigen::Vector3d(1.0, 0.0, 0.0);
  const auto rejected = estimate_msse(model_, MsseConfig{}, workspace_, {}, gate);
  EXPECT_EQ(rejected.status, RobustStatus::kNoHypothesis);
  EXPECT_TRUE(rejected.model.matrix().isIdentity(0.0));
}

TEST_F(MsseRigid, ThesisSingleRefitStillWorks) {
  MsseConfig config;
  config.refine_iterations = 0;
  const testing::Scene scene = scene_with(0.5, 6);
  const auto result = run(scene, config, false);
  ASSERT_TRUE(result.ok());
  EXPECT_TRUE(result.refined);
  EXPECT_LT(translation_difference_m(result.model, scene.T_t_s), 0.004);
  EXPECT_LT(rotation_difference_rad(result.model, scene.T_t_s) * kDegPerRad, 0.2);
  config.refit = false;
  const auto raw = run(scene, config, false);
  ASSERT_TRUE(raw.ok());
  EXPECT_FALSE(raw.refined);
}

}  // namespace
}  // namespace rankslam::robust

namespace rankslam::robust {
namespace {

// The one full sort per estimate orders by (residual, index); large inputs take a radix sort,
// which must give exactly the comparison sort's order, ties and zeros included.
TEST(SortResiduals, RadixAndComparisonSortsAgreeOnTiesZerosAndWideRanges) {
  std::mt19937_64 rng(7);
  for (const int n : {1, 2, 511, 512, 513, 4000, 16384}) {
    RobustWorkspace workspace(n);
    std::vector<double> values(static_cast<std::size_t>(n));
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    for (int i = 0; i < n; ++i) {
      double v = std::pow(10.0, -12.0 + 18.0 * uniform(rng));  // 1e-12 … 1e6
      if (i % 7 == 0) v = 0.25;                                   // many exact ties
      if (i % 11 == 0) v = 0.0;
      if (i % 13 == 0) v = -0.0;
      // Keys equal in their upper 32 bits, apart in the lower ones, in no particular order.
      if (i % 17 == 0) v = 1.0 + std::ldexp(static_cast<double>((i * 7919) % 1000), -40);
      // Runs of 7 such keys, each run in descending order of index.
      if (i % 23 == 0) v = 3.0 + 1e-3 * (i / 161) + std::ldexp(static_cast<double>(6 - i / 23 % 7), -40);
      values[static_cast<std::size_t>(i)] = v;
    }
    std::copy(values.begin(), values.end(), workspace.sq_residuals());
    detail::sort_residuals(workspace, n);
    std::vector<int> expected(static_cast<std::size_t>(n));
    std::iota(expected.begin(), expected.end(), 0);
    std::stable_sort(expected.begin(), expected.end(), [&](int a, int b) {
      return values[static_cast<std::size_t>(a)] < values[static_cast<std::size_t>(b)];
    });
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(workspace.order()[i], expected[static_cast<std::size_t>(i)]) << "n " << n << " rank " << i;
      ASSERT_EQ(workspace.sq_residuals()[i], values[static_cast<std::size_t>(expected[static_cast<std::size_t>(i)])]);
    }
  }
}

}  // namespace
}  // namespace rankslam::robust
