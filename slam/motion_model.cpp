#include "rankslam/slam/motion_model.hpp"

#include "rankslam/core/lie.hpp"

namespace rankslam::slam {

bool MotionModel::accept(const MotionEstimate& estimate, const Eigen::Isometry3d& T_world_target,
                         const Eigen::Isometry3d& T_world_previous, const Eigen::Isometry3d& predicted_step,
                         Eigen::Isometry3d& T_world_current, std::string_view& reason, bool resuming,
                         int reference_inliers) const {
  std::string_view why;
  if (!estimate.ok) {
    why = estimate.failure_reason;
  } else if (estimate.inliers < config_.min_inliers && estimate.icp_inliers < config_.min_icp_inliers) {
    why = "too few inliers";
  } else if (resuming && estimate.inliers < config_.reference_min_overlap * reference_inliers) {
    why = "too few inliers to resume tracking";
  } else if (!estimate.T_target_source.matrix().allFinite()) {
    why = "non-finite estimate";
  } else {
    const Eigen::Isometry3d T_world_candidate = T_world_target * estimate.T_target_source;
    if (resuming) {
      // The prediction is an extrapolation; the pose must still be one the camera can have
      // reached since its last measured pose: the prediction's gate, widened by one gate per
      // frame since then. (Without it, a plain corridor's end wall registered turned around
      // after a single failed frame.)
      const Eigen::Isometry3d since_tracked = T_world_last_tracked_.inverse() * T_world_candidate;
      const double frames_since_tracked = failed_in_a_row_ + 1.0;
      if (since_tracked.translation().norm() > frames_since_tracked * config_.max_deviation_translation_m ||
          lie::rotation_deg(since_tracked) > frames_since_tracked * config_.max_deviation_rotation_deg) {
        why = "motion since the last tracked frame far from any the camera can have made";
      }
    } else {
      const Eigen::Isometry3d step = T_world_previous.inverse() * T_world_candidate;
      const Eigen::Isometry3d deviation = predicted_step.inverse() * step;
      if (step.translation().norm() > config_.max_step_translation_m ||
          lie::rotation_deg(step) > config_.max_step_rotation_deg) {
        why = "implausible frame-to-frame motion";
      } else if (deviation.translation().norm() > config_.max_deviation_translation_m ||
                 lie::rotation_deg(deviation) > config_.max_deviation_rotation_deg) {
        why = "motion far from the prediction";
      }
    }
    if (why.empty()) {
      T_world_current = T_world_candidate;
      return true;
    }
  }
  if (reason.empty()) reason = why;  // the first attempt's reason is the telling one
  return false;
}

void MotionModel::finish(const Eigen::Isometry3d& T_world_previous, const nav::MotionPrior* prior,
                         FrameResult& result) {
  if (result.status == FrameStatus::kTracking) {
    result.T_world_cam = lie::renormalised(result.T_world_cam);
    // A frame that resumed tracking jumped from an extrapolated pose: that is no motion to go on
    // with, so the next prediction holds the pose.
    last_motion_ =
        resumed_ ? Eigen::Isometry3d::Identity() : lie::renormalised(T_world_previous.inverse() * result.T_world_cam);
    T_world_last_tracked_ = result.T_world_cam;
    failed_in_a_row_ = 0;
  } else if (result.status == FrameStatus::kWheels && prior != nullptr) {
    // The wheels carry the pose; their motion is also the best constant-velocity model should
    // the next frame come without a prior.
    last_motion_ = prior->T_previous_current;
    result.T_world_cam = lie::renormalised(T_world_previous * last_motion_);
    T_world_last_tracked_ = result.T_world_cam;
    failed_in_a_row_ = 0;
  } else if (result.status == FrameStatus::kFailed) {
    // Constant-velocity extrapolation keeps the pose continuous through a short gap; a long gap
    // holds the pose instead (see max_extrapolated_frames).
    if (++failed_in_a_row_ > config_.max_extrapolated_frames) last_motion_ = Eigen::Isometry3d::Identity();
    result.T_world_cam = lie::renormalised(T_world_previous * last_motion_);
  }
}

void MotionModel::relocalised(const Eigen::Isometry3d& T_world_cam) {
  last_motion_ = Eigen::Isometry3d::Identity();
  T_world_last_tracked_ = T_world_cam;
  failed_in_a_row_ = 0;
  resumed_ = false;
}

}  // namespace rankslam::slam
