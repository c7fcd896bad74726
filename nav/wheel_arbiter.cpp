#include "rankslam/nav/wheel_arbiter.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/units.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rankslam::nav {
namespace {

using lie::Matrix6d;
using lie::Vector6d;

double mahalanobis_sq(const Vector6d& residual, const Matrix6d& covariance) {
  const Eigen::LDLT<Matrix6d> factor(covariance);
  if (factor.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return residual.dot(factor.solve(residual));
}

}  // namespace

MotionPrior camera_motion_prior(double x_m, double y_m, double yaw_rad, const Eigen::Matrix3d& planar_covariance,
                                const Eigen::Isometry3d& T_base_cam) {
  Eigen::Isometry3d T_base_previous_base_current = Eigen::Isometry3d::Identity();
  T_base_previous_base_current.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_base_previous_base_current.translation() = Eigen::Vector3d(x_m, y_m, 0.0);
  const Eigen::Isometry3d T_cam_base = T_base_cam.inverse();
  MotionPrior prior;
  prior.T_previous_current = lie::renormalised(T_cam_base * T_base_previous_base_current * T_base_cam);

  // A change (δx, δy, δyaw) of the planar motion D is, to first order, D' = exp(ξ_base)·D with
  // ω = δyaw·z and v = (δx, δy, 0) − δyaw·z × t_D in the previous base frame; conjugating with
  // T_cam_base carries ξ into the previous camera frame (the adjoint: ω_c = R ω, v_c = R v + t × R ω).
  Eigen::Matrix<double, 6, 3> base_jacobian = Eigen::Matrix<double, 6, 3>::Zero();
  base_jacobian(2, 2) = 1.0;
  base_jacobian(3, 0) = 1.0;
  base_jacobian(4, 1) = 1.0;
  base_jacobian(3, 2) = y_m;
  base_jacobian(4, 2) = -x_m;
  const Eigen::Matrix<double, 6, 3> jacobian = lie::adjoint(T_cam_base) * base_jacobian;
  prior.covariance = jacobian * planar_covariance * jacobian.transpose();
  return prior;
}

WheelArbiter::WheelArbiter(const WheelArbiterConfig& config, const Eigen::Isometry3d& T_base_cam)
    : config_(config), T_base_cam_(T_base_cam) {
  window_.resize(static_cast<std::size_t>(std::max(1, config_.gate_window_frames)));
}

void WheelArbiter::interrupt() {
  clear_window();
  disagree_in_a_row_ = 0;
  slip_shaped_in_a_row_ = 0;
  turning_in_a_row_ = 0;
  vision_holds_ = false;
}

bool WheelArbiter::arbitrate(const MotionPrior& prior, const Eigen::Isometry3d& T_world_previous, int inliers,
                             Eigen::Isometry3d& T_world_cam, WheelCheck& check) {
  check.compared = true;
  const Eigen::Isometry3d registered = T_world_previous.inverse() * T_world_cam;
  const Vector6d residual = lie::log_so3_r3(registered * prior.T_previous_current.inverse());
  const double sigma_rad = deg_to_rad(config_.vision_sigma_deg);
  Vector6d vision_variance;
  vision_variance << Eigen::Vector3d::Constant(sigma_rad * sigma_rad),
      Eigen::Vector3d::Constant(config_.vision_sigma_m * config_.vision_sigma_m);
  const Matrix6d vision_covariance = vision_variance.asDiagonal();
  check.frame_distance_sq = mahalanobis_sq(residual, prior.covariance + vision_covariance);
  describe_in_base_frame(registered, prior.T_previous_current, check);

  // Over the window the residuals add up to (to first order) the registered motion over the
  // window against the wheels' over it; both noises add up frame by frame. (Registrations
  // against one key-frame would telescope, but new key-frames come every few frames.)
  Residual& slot = window_[window_next_];
  slot.residual = residual;
  slot.covariance = prior.covariance + vision_covariance;
  window_next_ = (window_next_ + 1) % window_.size();
  window_size_ = std::min(window_size_ + 1, window_.size());
  Vector6d window_residual = Vector6d::Zero();
  Matrix6d window_covariance = Matrix6d::Zero();
  for (std::size_t i = 0; i < window_size_; ++i) {
    window_residual += window_[i].residual;
    window_covariance += window_[i].covariance;
  }
  // Until the window is full its sum says no more than the frame alone.
  check.window_distance_sq =
      window_size_ == window_.size() ? mahalanobis_sq(window_residual, window_covariance) : 0.0;
  check.disagree = check.frame_distance_sq > config_.gate_chi2 || check.window_distance_sq > config_.gate_chi2;

  // A planar base can make the residual: nothing across the drive direction, in height or in
  // tilt beyond the vision noise. Along it registrations err widely in a plain corridor, so the
  // forward residual says too little to be tested.
  const bool planar = std::abs(check.lateral_residual_m) <= config_.vision_sigma_m &&
                      std::abs(check.height_residual_m) <= config_.vision_sigma_m &&
                      check.tilt_residual_deg <= config_.vision_sigma_deg;
  check.slip_shaped = planar && std::abs(check.yaw_residual_deg) >= config_.slip_yaw_deg;
  const bool strong = inliers >= config_.strong_inliers;

  if (vision_holds_) {
    // A disagreement vision won lasts for as long as vision keeps disagreeing in a way the base
    // can move. With vision holding the pose, a slip shows only its growth over one frame: it
    // lasts while that turns the same way at no less than the least rate that declares a slip.
    const bool still_slipping = slip_sign_ * check.yaw_residual_deg >= least_slip_turn_deg();
    if ((check.disagree || check.slip_shaped || still_slipping) && planar) {
      check.vision_trusted = true;
      check.disagree_in_a_row = ++disagree_in_a_row_;
      return true;
    }
    vision_holds_ = false;
    // What the window holds was vision's to explain; the wheels are compared afresh.
    clear_window();
  }
  // The heading run excuses vision's height and tilt, not much across: registrations that turn
  // about the scene instead of the camera (a turn with a sideways shift, for a second) are no slip.
  const int turn = check.yaw_residual_deg > 0.0 ? 1 : -1;
  if (std::abs(check.yaw_residual_deg) < config_.slip_yaw_deg ||
      std::abs(check.lateral_residual_m) > 2.0 * config_.vision_sigma_m) {
    turning_in_a_row_ = 0;
  } else {
    turning_in_a_row_ = turn == turning_sign_ ? turning_in_a_row_ + 1 : 1;
    turning_sign_ = turn;
  }
  slip_shaped_in_a_row_ = check.slip_shaped ? slip_shaped_in_a_row_ + 1 : 0;
  // A base moved without its wheels moves away from where they put it frame after frame, so each
  // frame of the run disagrees by itself; a window that still holds an earlier error does not count.
  const bool frame_disagrees = check.frame_distance_sq > config_.gate_chi2;
  disagree_in_a_row_ = frame_disagrees && !check.slip_shaped && planar && strong ? disagree_in_a_row_ + 1 : 0;
  const bool slip = slip_shaped_in_a_row_ >= config_.slip_min_frames || turning_in_a_row_ >= config_.slip_heading_frames;
  if (slip || disagree_in_a_row_ >= config_.override_min_frames) {
    // One wheel slipped, or the base moved without its wheels: vision keeps the pose.
    check.vision_trusted = true;
    check.slip_event = true;
    check.disagree_in_a_row = slip ? std::max(slip_shaped_in_a_row_, turning_in_a_row_) : disagree_in_a_row_;
    ++slip_events_;
    vision_holds_ = true;
    slip_sign_ = slip ? turn : 0;
    disagree_in_a_row_ = check.disagree_in_a_row;
    slip_shaped_in_a_row_ = 0;
    turning_in_a_row_ = 0;
    return true;
  }
  if (!check.disagree) {
    // Both measure the same motion: combine them by their covariances (a Kalman update of the
    // prior by the registration), exp(K·r)·prior with K = Σ_wheels (Σ_wheels + Σ_vision)⁻¹.
    // Motion the wheels cannot see (across the floor plane) has no wheel variance and keeps the
    // prior's value; a planar base cannot make it.
    const Matrix6d gain = prior.covariance * (prior.covariance + vision_covariance).inverse();
    const Vector6d correction = gain * residual;
    Eigen::Isometry3d update = Eigen::Isometry3d::Identity();
    const double angle = correction.head<3>().norm();
    if (angle > 0.0) update.linear() = Eigen::AngleAxisd(angle, correction.head<3>() / angle).toRotationMatrix();
    update.translation() = correction.tail<3>();
    T_world_cam = T_world_previous * (update * prior.T_previous_current);
    check.fused = true;
    return true;
  }
  // A registration error until shown otherwise: in a plain corridor a single disagreeing
  // registration errs far more than slip-free wheels do.
  check.wheels_trusted = true;
  check.disagree_in_a_row = std::max({slip_shaped_in_a_row_, turning_in_a_row_, disagree_in_a_row_});
  return false;
}

void WheelArbiter::describe_in_base_frame(const Eigen::Isometry3d& registered, const Eigen::Isometry3d& wheels,
                                          WheelCheck& check) const {
  const Eigen::Isometry3d T_cam_base = T_base_cam_.inverse();
  const Eigen::Isometry3d vision_base = T_base_cam_ * registered * T_cam_base;
  const Eigen::Isometry3d wheels_base = T_base_cam_ * wheels * T_cam_base;
  const Eigen::Vector3d step = vision_base.translation() - wheels_base.translation();
  check.forward_residual_m = step.x();
  check.lateral_residual_m = step.y();
  check.height_residual_m = step.z();
  const Eigen::Matrix3d& rotation = vision_base.linear();
  const Eigen::Matrix3d& wheel_rotation = wheels_base.linear();
  const double yaw_rad = std::remainder(
      std::atan2(rotation(1, 0), rotation(0, 0)) - std::atan2(wheel_rotation(1, 0), wheel_rotation(0, 0)),
      2.0 * std::numbers::pi);
  check.yaw_residual_deg = rad_to_deg(yaw_rad);
  // The wheels' rotation is about the vertical alone: vision's tilt of the vertical is all residual.
  check.tilt_residual_deg = rad_to_deg(std::acos(std::clamp(rotation(2, 2), -1.0, 1.0)));
}

}  // namespace rankslam::nav
