#pragma once

// What the SLAM loop reports of one frame, and of an accepted loop closure.

#include "rankslam/nav/wheel_arbiter.hpp"
#include "rankslam/slam/image_source.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <string_view>

namespace rankslam::slam {

/// What the loop made of one frame.
enum class FrameStatus : std::uint8_t {
  kFirstFrame,  ///< Defines the world frame.
  kTracking,    ///< Registered against the tracking key-frame or, failing that, the previous frame.
  kFailed,      ///< Registration failed, no wheel prior: the pose was propagated at constant velocity.
  kWheels,      ///< Registration failed or was overruled: the pose follows the wheel odometry prior.
  /// Tracking lost, a sudden drop of image inliers the search did not explain (the camera may
  /// have been carried off) or a loaded map not yet found, no wheel prior: the pose is unknown
  /// while the loop searches the stored key-frames (docs/methods.md §13).
  kLost,
};

[[nodiscard]] constexpr std::string_view to_string(FrameStatus status) {
  switch (status) {
    case FrameStatus::kFirstFrame: return "first-frame";
    case FrameStatus::kTracking: return "tracking";
    case FrameStatus::kFailed: return "failed";
    case FrameStatus::kWheels: return "wheels";
    case FrameStatus::kLost: return "lost";
  }
  return "unknown";
}

/// Per-stage wall time of one frame, milliseconds.
struct StageTimes {
  enum Stage : std::size_t { kPreprocess, kFeatures, kMatching, kEstimation, kIcp, kDense, kMapping };
  static constexpr std::size_t kCount = 7;
  static constexpr std::array<std::string_view, kCount> kNames = {"preprocess", "features", "matching", "estimation",
                                                                   "icp",        "dense",    "mapping"};
  std::array<double, kCount> ms{};
};

struct FrameResult {
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  FrameStatus status = FrameStatus::kFirstFrame;
  /// Why the frame failed; empty when it did not.
  std::string_view failure_reason;
  /// The image the features came from: infrared when the colour image was dark or absent.
  ImageSource image_source = ImageSource::kColour;
  int features = 0;
  int matches = 0;
  int inliers = 0;
  /// The registration's noise scale (MotionEstimate::noise_scale): 1 where its inliers fit as
  /// their predicted noise says, larger where they fit worse. Discounts its pose-graph edge.
  double noise_scale = 1.0;
  /// Fused mode: each kind's own MSSE inliers among its matches, and the photometric weight
  /// W_P of the combined estimate (W_G = 1 / W_P; docs/methods.md §6).
  int photometric_matches = 0;
  int photometric_inliers = 0;
  int geometric_matches = 0;
  int geometric_inliers = 0;
  double photometric_weight = 0.0;
  /// ICP refined the feature estimate (icp_mode on and the refinement accepted).
  bool icp_refined = false;
  /// The frame became the tracking key-frame the following frames register against.
  bool new_reference = false;
  /// After failed frames, the frame registered against the reference held since before them:
  /// tracking is back where it was, in the map.
  bool resumed = false;
  /// The frame was added to the map as a key-frame.
  bool keyframe = false;
  /// The frame's key-frame (the latest stored at or before it): its pose-graph node and the node's
  /// generation, and the frame's pose relative to it. SlamLoop::optimized_pose() re-expresses the
  /// frame after the graph was optimised.
  int keyframe_node = -1;
  std::uint32_t keyframe_generation = 0;
  Eigen::Isometry3d T_keyframe_cam = Eigen::Isometry3d::Identity();
  /// A loop closure was accepted at this frame: a key-frame, or a frame after one while its
  /// candidates are registered (SlamConfig::loop_candidates_per_frame).
  bool loop_closure = false;
  /// Loop-closure candidates registered at this frame.
  int loop_candidates = 0;
  /// The frame was found in the stored key-frames after tracking was lost (or in a loaded map):
  /// its pose is the relocalisation's, and map_correction moves the pose tracking held onto it.
  bool relocalised = false;
  /// Stored key-frames the frame was registered with while searching (relocalisation).
  int relocalisation_candidates = 0;
  /// With relocalised: this many frames just before this one had poses tracking gave away from
  /// the map (since the failure that started the search); they are withdrawn.
  int retracted_frames = 0;
  /// An optimised pose graph (or a relocalisation) was applied at this frame: the pose jumped by
  /// the map correction, which every tracked pose took: T_world_cam(after) = map_correction *
  /// T_world_cam(before). Identity when none was applied.
  bool graph_applied = false;
  Eigen::Isometry3d map_correction = Eigen::Isometry3d::Identity();
  /// Covariance of the frame's pose accumulated since the first frame (the odom pose, which a
  /// map correction does not change): ξ = (rotation vector, translation) applied on the right,
  /// T_world_cam·Exp(ξ), in the camera frame. Chained frame by frame from the frame each pose was
  /// measured from: the registration's covariance, the wheel prior's where the wheels carried or
  /// joined it, the tracker's floor where the motion model extrapolated it. False where the
  /// tracker keeps no chain (the geometric tracker).
  bool odom_covariance_valid = false;
  Eigen::Matrix<double, 6, 6> odom_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  nav::WheelCheck wheels;
  StageTimes times;
};

/// An accepted loop closure: the stored key-frame and the new one it was registered with, and
/// the relative pose the registration measured (the pose-graph edge).
struct LoopClosure {
  double stored_stamp_s = 0.0;
  double current_stamp_s = 0.0;
  Eigen::Isometry3d T_stored_current = Eigen::Isometry3d::Identity();
  int photometric_inliers = 0;
  int geometric_inliers = 0;
  /// The adaptive threshold ε when the closure was taken (inliers below it: corroborated by a
  /// neighbour of the stored key-frame).
  double threshold = 0.0;
};

}  // namespace rankslam::slam
