#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/geometry/frontend.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/nav/wheel_arbiter.hpp"
#include "rankslam/parallel/companion.hpp"
#include "rankslam/slam/backend.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/frame_images.hpp"
#include "rankslam/slam/frame_result.hpp"
#include "rankslam/slam/motion_estimator.hpp"
#include "rankslam/slam/orb_frontend.hpp"
#include "rankslam/slam/registrar.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <memory>

namespace rankslam::slam {

/// The loop's parts a tracker works with; all outlive it.
struct TrackerParts {
  const SlamConfig& config;
  const camera::DepthCameraModel& camera;
  FrameImages& images;
  Registrar& registrar;
  /// Configured by the tracker that uses it.
  geometry::GeometricFrontend& geometric;
  nav::WheelArbiter& arbiter;
  parallel::ThreadTeam& team;
  parallel::Companion& companion;
  const Backend& backend;
};

/// What the frame just tracked gives a key-frame made of it.
struct TrackedFeatures {
  const PhotometricFeatures* photometric = nullptr;  ///< Null: the tracker has none.
  const geometry::GeometricFeatures* geometric = nullptr;
  Registrar::Velocity velocity = Registrar::Velocity::Zero();
};

/// What a key-frame stores for the configured tracker.
struct KeyframeLayout {
  std::size_t photometric_features = 0;
  int geometric_features = 0;
  int cloud_points = 0;
};

/// Frame-to-frame tracking: registers each frame against earlier ones and gives its pose. One
/// implementation per registration strategy, chosen once by make_tracker. Per frame the loop calls
/// track, then (key-frame, loop closure, back-end) possibly keyframe_stored and correct, then
/// end_frame.
class Tracker {
 public:
  virtual ~Tracker() = default;

  /// Registers `frame` (with the wheel motion since the previous frame; null: none) and writes
  /// its status, pose, counts, times and wheel comparison into `result`.
  virtual void track(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, FrameResult& result) = 0;
  /// The frame just tracked's features, for a key-frame made of it.
  [[nodiscard]] virtual TrackedFeatures features() const = 0;
  /// Information of the sequential edge from the latest key-frame to the frame just tracked.
  [[nodiscard]] virtual Eigen::Matrix<double, 6, 6> keyframe_edge_information(const FrameResult& result) const = 0;
  /// The frame just tracked became a stored key-frame.
  virtual void keyframe_stored() {}
  /// Moves every pose the tracker holds by a world-frame correction (a back-end solve).
  virtual void correct(const Eigen::Isometry3d& correction) = 0;
  /// The frame just tracked was found in the map at `T_world_cam` with that pose's `covariance`:
  /// it becomes the reference the next frames register against, and `result` tracking.
  virtual void relocalise(const Eigen::Isometry3d& T_world_cam, const Eigen::Matrix<double, 6, 6>& covariance,
                          FrameResult& result) = 0;
  /// Ends the frame; `result` holds its final pose.
  virtual void end_frame(FrameResult& result) = 0;
};

/// The robust estimator of the configured mode's registrations.
[[nodiscard]] RobustEstimator robust_estimator(const SlamConfig& config);
/// The key-frame content of the configured mode's tracker.
[[nodiscard]] KeyframeLayout keyframe_layout(const SlamConfig& config);
/// The geometric front-end's buffers: room for the keypoints a frame keeps
/// (geometry.max_keypoints), no more.
[[nodiscard]] geometry::FrontendCapacities geometric_capacities(const SlamConfig& config);
/// The tracker of the configured mode, set up (allocates; throws std::invalid_argument for a
/// configuration its parts reject).
[[nodiscard]] std::unique_ptr<Tracker> make_tracker(const TrackerParts& parts);

}  // namespace rankslam::slam
