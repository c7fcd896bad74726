#include "rankslam/slam/motion_estimator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace rankslam::slam {
namespace {

// Matches of a known motion: points 1-3 m in front of the camera, the target points moved by
// the motion plus isotropic noise whose norm has RMS `noise_rms_m`, and every fifth match an
// outlier anywhere in the scene.
struct Matches {
  std::vector<Eigen::Vector3f> source;
  std::vector<Eigen::Vector3f> target;
};

Matches make_matches(double noise_rms_m, int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> lateral(-1.0, 1.0);
  std::uniform_real_distribution<double> depth(1.0, 3.0);
  std::normal_distribution<double> noise(0.0, noise_rms_m / std::sqrt(3.0));
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  T_target_source.linear() = Eigen::AngleAxisd(0.05, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix();
  T_target_source.translation() = Eigen::Vector3d(0.03, -0.01, 0.02);
  Matches matches;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d p(lateral(rng), lateral(rng), depth(rng));
    Eigen::Vector3d q = T_target_source * p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    if (i % 5 == 0) q = Eigen::Vector3d(lateral(rng), lateral(rng), depth(rng));
    matches.source.push_back(p.cast<float>());
    matches.target.push_back(q.cast<float>());
  }
  return matches;
}

double noise_scale_of(const Matches& matches, double predicted_sigma_m) {
  SlamConfig config;
  MotionEstimator estimator(config, RobustEstimator::kMsse, matches.source.size());
  const std::vector<double> sigma(matches.source.size(), predicted_sigma_m);
  const MotionEstimate estimate = estimator.estimate(matches.source, matches.target, sigma);
  EXPECT_TRUE(estimate.ok);
  return estimate.noise_scale;
}

TEST(MotionEstimator, NoiseScaleIsAboutOneWhenTheMatchesFitAsTheirPredictedNoiseSays) {
  const Matches matches = make_matches(0.01, 300, 7);
  const double scale = noise_scale_of(matches, 0.01);
  EXPECT_GT(scale, 0.6);
  EXPECT_LT(scale, 1.1);
}

TEST(MotionEstimator, NoiseScaleGrowsWithTheNoiseBeyondThePrediction) {
  const Matches matches = make_matches(0.03, 300, 7);
  const double scale = noise_scale_of(matches, 0.01);
  EXPECT_GT(scale, 2.0);
  EXPECT_LT(scale, 3.3);
}

TEST(MotionEstimator, NoiseScaleIsOneWithoutPredictedNoise) {
  const Matches matches = make_matches(0.03, 300, 7);
  SlamConfig config;
  MotionEstimator estimator(config, RobustEstimator::kMsse, matches.source.size());
  const MotionEstimate estimate = estimator.estimate(matches.source, matches.target);
  ASSERT_TRUE(estimate.ok);
  EXPECT_EQ(estimate.noise_scale, 1.0);
}

}  // namespace
}  // namespace rankslam::slam
