#pragma once

// The standard deviations PoseQuality sends, from a pose covariance: fixed-size Eigen only, no
// allocation.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rankslam::nav {

/// Position and yaw standard deviations of the base in the odom frame.
struct PoseSigmas {
  /// √ of the largest eigenvalue of the 2×2 (x, y) block of the position covariance in the odom
  /// frame: the standard deviation along the worst horizontal direction.
  double position_m = 0.0;
  double yaw_deg = 0.0;  ///< about the odom z axis
};

/// The sigmas of T_odom_base = T_base_cam·T_world_cam·T_cam_base (the odom frame is the base at
/// the first frame, the world frame the camera there), given the covariance of T_world_cam under
/// a right perturbation T_world_cam·Exp(ξ), ξ = (rotation vector, translation) in the camera
/// frame (slam::FrameResult::odom_covariance).
[[nodiscard]] PoseSigmas pose_sigmas(const Eigen::Isometry3d& T_world_cam, const Eigen::Matrix<double, 6, 6>& covariance,
                                     const Eigen::Isometry3d& T_base_cam);

/// The sigmas grown by wheel motion since the frame they were computed for: the base moved
/// `distance_m` (path length) and turned `turned_rad` (|yaw change|) on wheels whose travel has
/// variance `wheel_variance_per_m` per metre rolled, with track width `track_width_m`. The
/// differential-drive model: each wheel's travel error adds independently, so the position
/// variance grows by wheel_variance_per_m·distance / 2 along the path and the yaw variance by
/// 2·wheel_variance_per_m·(distance + track/2·turned) / track². The error heading error makes
/// across the path is not added: it is second order over the short spans between frames.
[[nodiscard]] PoseSigmas grown_by_wheels(const PoseSigmas& sigmas, double distance_m, double turned_rad,
                                         double wheel_variance_per_m, double track_width_m);

}  // namespace rankslam::nav
