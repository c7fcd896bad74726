#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/slam/camera.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/motion_estimator.hpp"
#include "rankslam/slam/orb_frontend.hpp"
#include "rankslam/slam/point_map.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <random>
#include <string_view>

namespace rankslam::slam {

/// What the loop made of one frame.
enum class FrameStatus : std::uint8_t {
  kFirstFrame,  ///< Defines the world frame.
  kTracking,    ///< Registered against the previous frame.
  kFailed,      ///< Registration failed; the pose was propagated at constant velocity.
};

[[nodiscard]] constexpr std::string_view to_string(FrameStatus status) {
  switch (status) {
    case FrameStatus::kFirstFrame: return "first-frame";
    case FrameStatus::kTracking: return "tracking";
    case FrameStatus::kFailed: return "failed";
  }
  return "unknown";
}

/// Per-stage wall time of one frame, milliseconds.
struct StageTimes {
  static constexpr std::size_t kCount = 5;
  static constexpr std::array<std::string_view, kCount> kNames = {"preprocess", "features", "matching",
                                                                   "estimation", "mapping"};
  std::array<double, kCount> ms{};
};

struct FrameResult {
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  FrameStatus status = FrameStatus::kFirstFrame;
  /// Why the frame failed; empty when it did not.
  std::string_view failure_reason;
  int features = 0;
  int matches = 0;
  int inliers = 0;
  bool keyframe = false;
  StageTimes times;
};

/// The per-frame SLAM loop: one call per RGB-D frame returns its pose and status. Everything it
/// needs is allocated at construction.
class SlamLoop {
 public:
  SlamLoop(const SlamConfig& config, const hal::Calibration& calibration);

  [[nodiscard]] FrameResult process(const hal::RgbdFrame& frame);

  [[nodiscard]] const PointMap& map() const { return map_; }
  [[nodiscard]] int keyframes() const { return keyframes_; }
  [[nodiscard]] const SlamConfig& config() const { return config_; }

 private:
  void add_keyframe_to_map(const hal::RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam);

  SlamConfig config_;
  DepthCameraModel camera_;
  OrbFrontend orb_;
  MutualHammingMatcher matcher_;
  MotionEstimator estimator_;
  PointMap map_;

  cv::Mat gray_;
  PhotometricFeatures previous_;
  PhotometricFeatures current_;
  std::vector<FeatureMatch> matches_;
  std::vector<Eigen::Vector3f> source_points_;
  std::vector<Eigen::Vector3f> target_points_;
  std::vector<double> correspondence_sigma_m_;

  bool has_previous_ = false;
  Eigen::Isometry3d T_world_previous_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d last_motion_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_last_keyframe_ = Eigen::Isometry3d::Identity();
  int keyframes_ = 0;
  std::mt19937 map_sampler_;
};

}  // namespace rankslam::slam
