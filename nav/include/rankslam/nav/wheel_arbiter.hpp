#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <vector>

namespace rankslam::nav {

/// The camera's motion since the previous frame as the wheel odometry measured it: the prediction
/// for registration and the fallback when registration fails. See camera_motion_prior().
struct MotionPrior {
  /// The camera at this frame in the camera frame at the previous frame processed.
  Eigen::Isometry3d T_previous_current = Eigen::Isometry3d::Identity();
  /// Covariance of the motion: a small motion ξ = (rotation vector, translation) applied on the
  /// left, T_previous_current = exp(ξ)·mean, expressed in the previous camera frame.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

/// The camera motion prior from a planar base motion (x, y, yaw of the base at the current frame
/// in the base frame at the previous one, with its 3×3 covariance in that frame) and the camera's
/// mounting T_base_cam: T_cam_prev_cam_cur = T_cam_base · T_base_prev_base_cur · T_base_cam, the
/// covariance propagated to first order.
[[nodiscard]] MotionPrior camera_motion_prior(double x_m, double y_m, double yaw_rad,
                                              const Eigen::Matrix3d& planar_covariance,
                                              const Eigen::Isometry3d& T_base_cam);

/// How vision and the wheel prior related on one frame (all false/0 without a prior).
struct WheelCheck {
  bool prior_given = false;
  /// A registration was accepted and compared with the prior.
  bool compared = false;
  /// Squared Mahalanobis distance of the registered motion from the prior, this frame alone and
  /// summed over the last gate_window_frames compared frames.
  double frame_distance_sq = 0.0;
  double window_distance_sq = 0.0;
  /// The registered motion less the wheels', in the base frame at the previous frame: along
  /// the drive direction, across it, and about the vertical (what the wheels measure), then
  /// height, roll and pitch (what a planar base cannot make).
  double forward_residual_m = 0.0;
  double lateral_residual_m = 0.0;
  double yaw_residual_deg = 0.0;
  double height_residual_m = 0.0;
  double tilt_residual_deg = 0.0;
  /// Either distance beyond gate_chi2.
  bool disagree = false;
  /// The residual is what one slipping wheel leaves: a heading residual of slip_yaw_deg or
  /// more, and across the drive direction, in height and in tilt no more than the vision noise.
  bool slip_shaped = false;
  /// They agreed: the pose is the covariance-weighted combination of the registration and the prior.
  bool fused = false;
  /// Vision won: slip-shaped residuals for slip_min_frames in a row, a heading residual turning
  /// one way for slip_heading_frames, or a strong registration (strong_inliers) disagreeing
  /// otherwise, as the base can move, for override_min_frames; and for as long as the
  /// disagreement then lasts.
  bool vision_trusted = false;
  /// Wheels won: a registration disagreed and was replaced by the prior.
  bool wheels_trusted = false;
  /// Frames in a row of the current kind of disagreement: slip-shaped, or strong and otherwise
  /// disagreeing.
  int disagree_in_a_row = 0;
  /// This frame started a disagreement that vision won (counted in WheelArbiter::slip_events()).
  bool slip_event = false;
};

/// Options of the wheel/vision arbiter. The registered motion is compared with the wheels' under
/// the wheel covariance plus a per-frame vision noise, frame by frame and summed over a window
/// (slip adds up there while noise grows with its square root); the gate is the chi-square
/// 99.9 % quantile of 6 degrees of freedom. One wheel slipping leaves a residual a planar base
/// can make (about the vertical, nothing across, in height or in tilt beyond the vision noise);
/// any other disagreement is a registration error until strong vision has disagreed for
/// override_min_frames in a row (the robot pushed or carried). docs/results.md has the
/// measurements behind the defaults.
struct WheelArbiterConfig {
  double vision_sigma_m = 0.02;
  double vision_sigma_deg = 1.0;
  double gate_chi2 = 22.46;
  int gate_window_frames = 8;
  int strong_inliers = 40;
  double slip_yaw_deg = 0.8;
  int slip_min_frames = 3;
  int slip_heading_frames = 8;
  int override_min_frames = 15;

  /// Calls visit(name, field, min, max, unit, doc) for every parameter; the names are the keys of
  /// the configuration's `slam:` section.
  template <class Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("wheel_vision_sigma_m", vision_sigma_m, 1e-5, 1.0, "m",
          "per-frame translation noise of a registration, in the comparison with the wheel prior");
    visit("wheel_vision_sigma_deg", vision_sigma_deg, 1e-3, 45.0, "deg",
          "per-frame rotation noise of a registration, in the comparison with the wheel prior");
    visit("wheel_gate_chi2", gate_chi2, 1.0, 1000.0, "",
          "squared Mahalanobis distance beyond which vision and wheels disagree (6 degrees of freedom)");
    visit("wheel_gate_window_frames", gate_window_frames, 1, 100, "",
          "compared frames whose residuals from the wheel prior are summed for the window test");
    visit("wheel_strong_inliers", strong_inliers, 3, 10000, "",
          "a registration with this many inliers can overrule wheels it disagrees with as no slip does");
    visit("wheel_slip_yaw_deg", slip_yaw_deg, 0.0, 45.0, "deg",
          "heading residual from which vision otherwise agreeing with the wheels points to one slipping wheel");
    visit("wheel_slip_min_frames", slip_min_frames, 1, 1000, "",
          "frames in a row of slip-shaped residuals that make a wheel-slip event (vision keeps the pose)");
    visit("wheel_slip_heading_frames", slip_heading_frames, 1, 1000, "",
          "frames in a row of a heading residual of wheel_slip_yaw_deg turning one way that make a wheel-slip event");
    visit("wheel_override_min_frames", override_min_frames, 1, 100000, "",
          "frames in a row of strong vision disagreeing otherwise with the wheels before vision keeps the pose");
  }
};

/// Decides, frame by frame, whether an accepted registration or the wheel prior keeps the pose:
/// they agree (the pose is their covariance-weighted combination), the wheels overrule the
/// registration, or vision wins a disagreement the wheels cannot explain (a slipping wheel, a
/// base moved without its wheels). Allocates only at construction.
class WheelArbiter {
 public:
  WheelArbiter(const WheelArbiterConfig& config, const Eigen::Isometry3d& T_base_cam);

  /// Compares the registered pose T_world_cam (the camera at this frame; the previous frame at
  /// T_world_previous) with the prior, records it in `check`, and where they agree replaces
  /// T_world_cam by the combination. False when the wheels overrule the registration.
  [[nodiscard]] bool arbitrate(const MotionPrior& prior, const Eigen::Isometry3d& T_world_previous, int inliers,
                               Eigen::Isometry3d& T_world_cam, WheelCheck& check);
  /// A frame that was not compared: the window and the runs count consecutive compared frames.
  void interrupt();

  /// Disagreements with the wheels that vision won so far.
  [[nodiscard]] int slip_events() const { return slip_events_; }
  /// The least heading a slip adds per frame: slip_yaw_deg reached in slip_min_frames.
  [[nodiscard]] double least_slip_turn_deg() const { return config_.slip_yaw_deg / config_.slip_min_frames; }
  [[nodiscard]] const WheelArbiterConfig& config() const { return config_; }

 private:
  /// The registered motion less the wheels', in base terms (the WheelCheck's *_residual fields).
  void describe_in_base_frame(const Eigen::Isometry3d& registered, const Eigen::Isometry3d& wheels,
                              WheelCheck& check) const;
  void clear_window() {
    window_size_ = 0;
    window_next_ = 0;
  }

  /// A compared frame's residual from the prior, for the window test.
  struct Residual {
    Eigen::Matrix<double, 6, 1> residual = Eigen::Matrix<double, 6, 1>::Zero();
    Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  };

  WheelArbiterConfig config_;
  Eigen::Isometry3d T_base_cam_;
  /// The last compared frames' residuals (a ring of gate_window_frames).
  std::vector<Residual> window_;
  std::size_t window_next_ = 0;
  std::size_t window_size_ = 0;
  int slip_shaped_in_a_row_ = 0;
  /// Frames in a row whose heading residual reached slip_yaw_deg turning turning_sign_'s way.
  int turning_in_a_row_ = 0;
  int turning_sign_ = 0;
  int disagree_in_a_row_ = 0;
  /// Vision won the current disagreement.
  bool vision_holds_ = false;
  /// The heading residual's sign when vision won for a slip; 0 when it won otherwise.
  int slip_sign_ = 0;
  int slip_events_ = 0;
};

}  // namespace rankslam::nav
