#include "rankslam/slam/tracker.hpp"

#include <gtest/gtest.h>

namespace rankslam::slam {
namespace {

SlamConfig config_of(Mode mode) {
  SlamConfig config;
  config.mode = mode;
  return config;
}

TEST(TrackerFactory, TheModeChoosesTheEstimatorAndWhatAKeyframeKeeps) {
  EXPECT_EQ(robust_estimator(config_of(Mode::kBaseline)), RobustEstimator::kRansac);
  for (const Mode mode : {Mode::kPhotometric, Mode::kGeometric, Mode::kFused}) {
    EXPECT_EQ(robust_estimator(config_of(mode)), RobustEstimator::kMsse) << to_string(mode);
  }
  const SlamConfig defaults;
  // The fixed-memory extractor's cap (orb_extractor_test); OpenCV's ORB gets twice the room.
  const auto orb = static_cast<std::size_t>(defaults.orb_features);
  SlamConfig opencv = config_of(Mode::kFused);
  opencv.orb_implementation = OrbImplementation::kOpenCv;
  EXPECT_EQ(keyframe_layout(opencv).photometric_features, 2 * orb);
  for (const Mode mode : {Mode::kBaseline, Mode::kPhotometric}) {
    const KeyframeLayout layout = keyframe_layout(config_of(mode));
    EXPECT_EQ(layout.photometric_features, orb) << to_string(mode);
    EXPECT_EQ(layout.geometric_features, 0) << to_string(mode);
    EXPECT_EQ(layout.cloud_points, 0) << to_string(mode);
  }
  const KeyframeLayout geometric = keyframe_layout(config_of(Mode::kGeometric));
  EXPECT_EQ(geometric.photometric_features, 0U);
  EXPECT_EQ(geometric.geometric_features, defaults.geometry.max_keypoints);
  EXPECT_EQ(geometric.cloud_points, 0);
  const KeyframeLayout fused = keyframe_layout(config_of(Mode::kFused));
  EXPECT_EQ(fused.photometric_features, orb);
  EXPECT_EQ(fused.geometric_features, defaults.geometry.max_keypoints);
  EXPECT_EQ(fused.cloud_points, defaults.keyframe_cloud_points);
}

TEST(TrackerFactory, TheGeometricFrontEndTakesTheLoopsSharedParameters) {
  SlamConfig config;
  config.min_depth_m = 0.45;
  config.max_depth_m = 3.5;
  config.msse_hypotheses = 321;
  config.seed = 9;
  config.geometry.max_keypoints = 123;
  const geometry::GeometryConfig frontend = config.geometric_frontend();
  EXPECT_DOUBLE_EQ(frontend.min_depth_m, 0.45);
  EXPECT_DOUBLE_EQ(frontend.max_depth_m, 3.5);
  EXPECT_EQ(frontend.msse_hypotheses, 321);
  EXPECT_EQ(frontend.seed, 9);
  EXPECT_EQ(frontend.max_keypoints, 123);
}

}  // namespace
}  // namespace rankslam::slam
