#pragma once

#include "rankslam/nav/wheel_arbiter.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/frame_result.hpp"
#include "rankslam/slam/motion_estimator.hpp"

#include <Eigen/Geometry>

#include <string_view>

namespace rankslam::slam {

/// The camera's motion model between registrations: predicts each frame's motion (the wheel
/// prior's, else constant velocity), checks a registration against what the camera can have done,
/// and carries the pose through frames that failed (extrapolating a short gap, holding a long one).
class MotionModel {
 public:
  explicit MotionModel(const SlamConfig& config) : config_(config) {}

  /// Motion predicted from the previous frame to this one: the prior's, else constant velocity.
  [[nodiscard]] const Eigen::Isometry3d& predicted(const nav::MotionPrior* prior) const {
    return prior != nullptr ? prior->T_previous_current : last_motion_;
  }
  /// After failed frames without wheels the prediction extrapolates the last motion, which may be
  /// the wrong estimate that started the failure: registrations are then checked against the
  /// last measured pose instead (see accept).
  [[nodiscard]] bool resuming(const nav::MotionPrior* prior) const {
    return failed_in_a_row_ > 0 && prior == nullptr;
  }

  /// Checks an estimate of T_target_current; on success writes T_world_current, otherwise
  /// `reason` (when still empty). `predicted_step` is the motion expected from the previous
  /// frame. `resuming`: after failed frames, against the reference, whose pose was measured; the
  /// estimate then needs reference_min_overlap of `reference_inliers` and a pose the camera can
  /// have reached since its last measured one.
  [[nodiscard]] bool accept(const MotionEstimate& estimate, const Eigen::Isometry3d& T_world_target,
                            const Eigen::Isometry3d& T_world_previous, const Eigen::Isometry3d& predicted_step,
                            Eigen::Isometry3d& T_world_current, std::string_view& reason, bool resuming = false,
                            int reference_inliers = 0) const;

  /// The current frame's registration resumed tracking after failed frames (or did not).
  void set_resumed(bool resumed) { resumed_ = resumed; }
  /// Ends a registered frame: a tracked one updates the model; a failed one takes the wheels'
  /// motion (kWheels) or extrapolates; writes the pose into `result`.
  void finish(const Eigen::Isometry3d& T_world_previous, const nav::MotionPrior* prior, FrameResult& result);
  /// The current frame was relocalised at T_world_cam: the motion since the last tracked frame is
  /// unknown, so the next prediction holds the pose.
  void relocalised(const Eigen::Isometry3d& T_world_cam);

 private:
  const SlamConfig& config_;
  /// T_previous_current of the last registered frame: the constant-velocity model.
  Eigen::Isometry3d last_motion_ = Eigen::Isometry3d::Identity();
  /// Failed frames since the last registered one.
  int failed_in_a_row_ = 0;
  /// The current frame resumed tracking against the reference after failed frames.
  bool resumed_ = false;
  /// Pose of the last registered frame.
  Eigen::Isometry3d T_world_last_tracked_ = Eigen::Isometry3d::Identity();
};

}  // namespace rankslam::slam
