// The one place that reads SlamConfig::mode: which tracker, estimator and key-frame content it
// stands for.
#include "feature_tracker.hpp"
#include "geometric_tracker.hpp"
#include "rankslam/slam/tracker.hpp"

#include <stdexcept>
#include <string>

namespace rankslam::slam {

RobustEstimator robust_estimator(const SlamConfig& config) {
  return config.mode == Mode::kBaseline ? RobustEstimator::kRansac : RobustEstimator::kMsse;
}

KeyframeLayout keyframe_layout(const SlamConfig& config) {
  // The fixed-memory extractor keeps at most orb_features keypoints (ROS2D's too: it describes up
  // to that many); OpenCV's ORB may return more.
  const auto orb = static_cast<std::size_t>(config.orb_features) *
                   (config.orb_implementation == OrbImplementation::kFixedMemory ? 1U : 2U);
  switch (config.mode) {
    case Mode::kBaseline:
    case Mode::kPhotometric: return {orb, 0, 0};
    case Mode::kGeometric: return {0, config.geometry.max_keypoints, 0};
    case Mode::kFused: return {orb, config.geometry.max_keypoints, config.keyframe_cloud_points};
  }
  throw std::invalid_argument("slam.mode: unknown mode " + std::to_string(static_cast<int>(config.mode)));
}

geometry::FrontendCapacities geometric_capacities(const SlamConfig& config) {
  geometry::FrontendCapacities capacities;
  capacities.max_keypoints = config.geometry.max_keypoints;
  return capacities;
}

std::unique_ptr<Tracker> make_tracker(const TrackerParts& parts) {
  switch (parts.config.mode) {
    case Mode::kBaseline:
    case Mode::kPhotometric: return std::make_unique<FeatureTracker>(parts, false);
    case Mode::kGeometric: return std::make_unique<GeometricTracker>(parts);
    case Mode::kFused: return std::make_unique<FeatureTracker>(parts, true);
  }
  throw std::invalid_argument("slam.mode: unknown mode " + std::to_string(static_cast<int>(parts.config.mode)));
}

}  // namespace rankslam::slam
