#include "rankslam/nav/wheel_odometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

namespace rankslam::nav {
namespace {

// Counter read jitter and the sampling instant each allow about one tick either way; two
// frames' worth of it is never taken for implausible speed.
constexpr double kTickSlack = 2.0;

// Below this |Δθ| the chord factor and its derivative use their Taylor series (the closed
// forms lose every digit at Δθ → 0); the fourth-order term is then below 1e-14.
constexpr double kSeriesBelow_rad = 1e-3;

bool within(double value, double min, double max) { return value >= min && value <= max; }

std::string out_of_range(const char* name, double value, const char* range) {
  std::ostringstream text;
  text << name << " = " << value << " is outside " << range;
  return text.str();
}

// Chord length of an arc over its length: f(a) = sin(a/2) / (a/2), and f'(a).
double chord_factor(double turn_rad) {
  if (std::abs(turn_rad) < kSeriesBelow_rad) return 1.0 - turn_rad * turn_rad / 24.0;
  return std::sin(0.5 * turn_rad) / (0.5 * turn_rad);
}

double chord_factor_derivative(double turn_rad) {
  if (std::abs(turn_rad) < kSeriesBelow_rad) return -turn_rad / 12.0;
  return (turn_rad * std::cos(0.5 * turn_rad) - 2.0 * std::sin(0.5 * turn_rad)) / (turn_rad * turn_rad);
}

// Jacobian of p ⊕ δ with respect to p for a world-frame displacement d of the position:
// a yaw error at p swings the later position about p.
Eigen::Matrix3d lever_jacobian(double dx_m, double dy_m) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Identity();
  J(0, 2) = -dy_m;
  J(1, 2) = dx_m;
  return J;
}

}  // namespace

Pose2d compose(const Pose2d& T_a_b, const Pose2d& T_b_c) {
  const double c = std::cos(T_a_b.yaw_rad);
  const double s = std::sin(T_a_b.yaw_rad);
  return {T_a_b.x_m + c * T_b_c.x_m - s * T_b_c.y_m, T_a_b.y_m + s * T_b_c.x_m + c * T_b_c.y_m,
          wrap_angle(T_a_b.yaw_rad + T_b_c.yaw_rad)};
}

Pose2d inverse(const Pose2d& T_a_b) {
  const double c = std::cos(T_a_b.yaw_rad);
  const double s = std::sin(T_a_b.yaw_rad);
  return {-c * T_a_b.x_m - s * T_a_b.y_m, s * T_a_b.x_m - c * T_a_b.y_m, wrap_angle(-T_a_b.yaw_rad)};
}

Eigen::Isometry3d to_isometry3d(const Pose2d& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(pose.yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(pose.x_m, pose.y_m, 0.0);
  return T;
}

std::string validate(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels) {
  if (!within(config.max_wheel_speed_mps, 0.1, 20.0)) {
    return out_of_range("max_wheel_speed_mps", config.max_wheel_speed_mps, "0.1 .. 20");
  }
  if (!within(config.max_frame_gap_s, 0.02, 1.0)) return out_of_range("max_frame_gap_s", config.max_frame_gap_s, "0.02 .. 1");
  if (!within(config.wheel_variance_per_m, 0.0, 1.0)) {
    return out_of_range("wheel_variance_per_m", config.wheel_variance_per_m, "0 .. 1");
  }
  if (config.history_capacity < 2 || config.history_capacity > 1'000'000) {
    return "history_capacity = " + std::to_string(config.history_capacity) + " is outside 2 .. 1000000";
  }
  if (!(wheels.radius_m > 0.0) || !std::isfinite(wheels.radius_m)) {
    return out_of_range("wheels.radius_m", wheels.radius_m, "(0, inf)");
  }
  if (!(wheels.track_width_m > 0.0) || !std::isfinite(wheels.track_width_m)) {
    return out_of_range("wheels.track_width_m", wheels.track_width_m, "(0, inf)");
  }
  if (wheels.ticks_per_revolution <= 0) {
    return "wheels.ticks_per_revolution = " + std::to_string(wheels.ticks_per_revolution) + " is not positive";
  }
  return {};
}

const char* to_string(WheelFrameResult result) {
  switch (result) {
    case WheelFrameResult::kBaseline: return "baseline";
    case WheelFrameResult::kIntegrated: return "integrated";
    case WheelFrameResult::kIntegratedAcrossGap: return "integrated across gap";
    case WheelFrameResult::kTimestampJump: return "timestamp jump";
    case WheelFrameResult::kCountersRebased: return "counters rebased";
    case WheelFrameResult::kDuplicate: return "duplicate";
    case WheelFrameResult::kOutOfOrder: return "out of order";
    case WheelFrameResult::kImplausible: return "implausible";
    case WheelFrameResult::kEncoderFault: return "encoder fault";
    case WheelFrameResult::kNotWheelFrame: return "not a wheel frame";
    case WheelFrameResult::kMalformed: return "malformed";
  }
  return "unknown";
}

const char* to_string(RelativeMotionStatus status) {
  switch (status) {
    case RelativeMotionStatus::kOk: return "ok";
    case RelativeMotionStatus::kNotInHistory: return "not in history";
    case RelativeMotionStatus::kDiscontinuous: return "discontinuous";
    case RelativeMotionStatus::kWrongOrder: return "wrong order";
  }
  return "unknown";
}

WheelOdometry::WheelOdometry(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels)
    : config_(config),
      wheels_(wheels),
      metres_per_tick_(2.0 * std::numbers::pi * wheels.radius_m / std::max(1, wheels.ticks_per_revolution)),
      history_(static_cast<std::size_t>(std::max(2, config.history_capacity))) {}

WheelFrameResult WheelOdometry::update(const hal::CanFrame& frame) {
  if (frame.id != wheels_.can_id || frame.extended) return WheelFrameResult::kNotWheelFrame;
  const auto ticks = decode_wheel_ticks(frame);
  if (!ticks) {
    ++stats_.frames_received;
    ++stats_.malformed;
    return WheelFrameResult::kMalformed;
  }
  return update(*ticks, frame.stamp_ns);
}

WheelFrameResult WheelOdometry::update(const WheelTicks& ticks, std::int64_t stamp_ns) {
  ++stats_.frames_received;
  if (ticks.left_fault || ticks.right_fault) {
    // Counts read while an encoder is faulty mean nothing; start afresh from the next good frame.
    ++stats_.encoder_faults;
    have_baseline_ = false;
    return WheelFrameResult::kEncoderFault;
  }
  if (!have_baseline_) {
    start_baseline(ticks, stamp_ns);
    return WheelFrameResult::kBaseline;
  }
  if (stamp_ns == last_seen_.stamp_ns || ticks.rolling_counter == last_seen_.ticks.rolling_counter) {
    ++stats_.duplicates;
    return WheelFrameResult::kDuplicate;
  }
  // The rolling counter orders frames independently of the receiver's clock: ahead by 1..127
  // is a later frame, anything else an earlier one.
  const auto counter_step = static_cast<std::uint8_t>(ticks.rolling_counter - last_seen_.ticks.rolling_counter);
  const bool counter_ahead = counter_step < 128;
  if (stamp_ns < last_seen_.stamp_ns) {
    if (!counter_ahead) {
      ++stats_.out_of_order;
      return WheelFrameResult::kOutOfOrder;
    }
    // A later frame with an earlier stamp: the clock went back. The old stamps no longer
    // compare with the new ones, so the history restarts too.
    ++stats_.timestamp_jumps_backward;
    start_baseline(ticks, stamp_ns);
    return WheelFrameResult::kTimestampJump;
  }
  const auto max_gap_ns = static_cast<std::int64_t>(std::llround(config_.max_frame_gap_s * 1e9));
  if (stamp_ns - baseline_.stamp_ns > max_gap_ns) {
    ++stats_.timestamp_jumps_forward;
    start_baseline(ticks, stamp_ns);
    return WheelFrameResult::kTimestampJump;
  }
  if (!plausible(baseline_, ticks, stamp_ns)) {
    if (have_rejected_ && stamp_ns > rejected_.stamp_ns && plausible(rejected_, ticks, stamp_ns)) {
      // Two frames in a row agree with each other and not with the baseline: the counters
      // were restarted (controller reset), not corrupted.
      ++stats_.counter_rebases;
      start_baseline(ticks, stamp_ns);
      return WheelFrameResult::kCountersRebased;
    }
    ++stats_.implausible;
    rejected_ = {ticks, stamp_ns};
    have_rejected_ = true;
    last_seen_ = rejected_;
    return WheelFrameResult::kImplausible;
  }
  int missing_frames = 0;
  if (counter_ahead) {
    missing_frames = counter_step - 1;
  } else {
    // Newer stamp but the counter is behind: a late frame or a restarted counter. Absolute
    // tick counts make integrating it harmless; how many frames were lost is unknown.
    ++stats_.rolling_counter_jumps;
  }
  integrate(ticks, stamp_ns, missing_frames);
  if (missing_frames > 0) {
    ++stats_.gaps;
    stats_.frames_missing += static_cast<std::uint64_t>(missing_frames);
    return WheelFrameResult::kIntegratedAcrossGap;
  }
  return WheelFrameResult::kIntegrated;
}

void WheelOdometry::start_baseline(const WheelTicks& ticks, std::int64_t stamp_ns) {
  baseline_ = {ticks, stamp_ns};
  last_seen_ = baseline_;
  have_baseline_ = true;
  have_rejected_ = false;
  state_.initialised = true;
  state_.stamp_ns = stamp_ns;
  state_.linear_velocity_mps = 0.0;
  state_.angular_velocity_rps = 0.0;
  // The history must stay sorted by stamp for interpolation.
  if (history_size_ > 0 && stamp_ns <= newest_stamp_ns()) history_size_ = 0;
  HistoryEntry entry;
  entry.stamp_ns = stamp_ns;
  entry.T_odom_base = state_.T_odom_base;
  entry.connected = false;
  push_history(entry);
}

bool WheelOdometry::plausible(const CounterFrame& from, const WheelTicks& to, std::int64_t stamp_ns) const {
  const double dt_s = static_cast<double>(stamp_ns - from.stamp_ns) * 1e-9;
  const double max_ticks = config_.max_wheel_speed_mps * dt_s / metres_per_tick_ + kTickSlack;
  const auto left = std::abs(wheel_tick_delta(from.ticks.left_ticks, to.left_ticks));
  const auto right = std::abs(wheel_tick_delta(from.ticks.right_ticks, to.right_ticks));
  return static_cast<double>(left) <= max_ticks && static_cast<double>(right) <= max_ticks;
}

void WheelOdometry::integrate(const WheelTicks& ticks, std::int64_t stamp_ns, int missing_frames) {
  const double left_m = wheel_tick_delta(baseline_.ticks.left_ticks, ticks.left_ticks) * metres_per_tick_;
  const double right_m = wheel_tick_delta(baseline_.ticks.right_ticks, ticks.right_ticks) * metres_per_tick_;
  const double dt_s = static_cast<double>(stamp_ns - baseline_.stamp_ns) * 1e-9;
  const double b = wheels_.track_width_m;

  // Exact arc: the base origin moves along a circle (a line when Δθ = 0) from θ to θ + Δθ, so
  // the displacement is the chord, of length Δs·f(Δθ), in the direction θ + Δθ/2.
  const double ds = 0.5 * (right_m + left_m);
  const double dtheta = (right_m - left_m) / b;
  const double f = chord_factor(dtheta);
  const double df = chord_factor_derivative(dtheta);
  const double chord = ds * f;
  const double heading = state_.T_odom_base.yaw_rad + 0.5 * dtheta;
  const double c = std::cos(heading);
  const double s = std::sin(heading);
  const double dx = chord * c;
  const double dy = chord * s;

  // Σ' = F Σ Fᵀ + G Σ_Δ Gᵀ with F = ∂p'/∂p and G = ∂p'/∂(Δs_r, Δs_l)
  //    = ∂p'/∂(Δs, Δθ) · ∂(Δs, Δθ)/∂(Δs_r, Δs_l).
  Eigen::Matrix<double, 3, 2> G_arc;
  G_arc << f * c, ds * df * c - 0.5 * chord * s,  //
      f * s, ds * df * s + 0.5 * chord * c,       //
      0.0, 1.0;
  Eigen::Matrix2d arc_from_wheels;
  arc_from_wheels << 0.5, 0.5,  //
      1.0 / b, -1.0 / b;
  const Eigen::Matrix<double, 3, 2> G = G_arc * arc_from_wheels;
  const Eigen::Vector2d wheel_variance(config_.wheel_variance_per_m * std::abs(right_m),
                                       config_.wheel_variance_per_m * std::abs(left_m));
  const Eigen::Matrix3d step_noise = G * wheel_variance.asDiagonal() * G.transpose();
  const Eigen::Matrix3d F = lever_jacobian(dx, dy);
  state_.covariance = F * state_.covariance * F.transpose() + step_noise;
  state_.covariance = 0.5 * (state_.covariance + state_.covariance.transpose()).eval();

  state_.T_odom_base.x_m += dx;
  state_.T_odom_base.y_m += dy;
  state_.T_odom_base.yaw_rad = wrap_angle(state_.T_odom_base.yaw_rad + dtheta);
  state_.stamp_ns = stamp_ns;
  state_.linear_velocity_mps = dt_s > 0.0 ? ds / dt_s : 0.0;
  state_.angular_velocity_rps = dt_s > 0.0 ? dtheta / dt_s : 0.0;
  state_.distance_m += std::abs(ds);
  state_.turned_rad += std::abs(dtheta);
  ++stats_.frames_integrated;

  baseline_ = {ticks, stamp_ns};
  last_seen_ = baseline_;
  have_rejected_ = false;

  HistoryEntry entry;
  entry.stamp_ns = stamp_ns;
  entry.T_odom_base = state_.T_odom_base;
  entry.step_noise = step_noise;
  entry.step_turn_rad = dtheta;
  entry.connected = true;
  entry.missing_frames = static_cast<std::uint16_t>(std::clamp(missing_frames, 0, 0xFFFF));
  push_history(entry);
}

void WheelOdometry::push_history(const HistoryEntry& entry) {
  const std::size_t capacity = history_.size();
  if (history_size_ == capacity) {
    history_[history_head_] = entry;
    history_head_ = (history_head_ + 1) % capacity;
  } else {
    history_[(history_head_ + history_size_) % capacity] = entry;
    ++history_size_;
  }
}

const WheelOdometry::HistoryEntry& WheelOdometry::history(std::size_t logical_index) const {
  return history_[(history_head_ + logical_index) % history_.size()];
}

std::int64_t WheelOdometry::oldest_stamp_ns() const { return history_size_ > 0 ? history(0).stamp_ns : 0; }

std::int64_t WheelOdometry::newest_stamp_ns() const {
  return history_size_ > 0 ? history(history_size_ - 1).stamp_ns : 0;
}

bool WheelOdometry::locate(std::int64_t stamp_ns, HistoryPosition& position) const {
  if (history_size_ == 0 || stamp_ns < oldest_stamp_ns() || stamp_ns > newest_stamp_ns()) return false;
  // Last entry with a stamp <= stamp_ns (binary search over the ring's logical order).
  std::size_t low = 0;
  std::size_t high = history_size_ - 1;
  while (low < high) {
    const std::size_t mid = (low + high + 1) / 2;
    if (history(mid).stamp_ns <= stamp_ns) {
      low = mid;
    } else {
      high = mid - 1;
    }
  }
  position.index = low;
  position.fraction = 0.0;
  if (low + 1 < history_size_) {
    const std::int64_t begin = history(low).stamp_ns;
    const std::int64_t end = history(low + 1).stamp_ns;
    position.fraction = static_cast<double>(stamp_ns - begin) / static_cast<double>(end - begin);
  }
  return true;
}

Pose2d WheelOdometry::interpolate(const HistoryPosition& position) const {
  const Pose2d& from = history(position.index).T_odom_base;
  if (position.fraction == 0.0) return from;
  const HistoryEntry& next = history(position.index + 1);
  const Pose2d& to = next.T_odom_base;
  const double t = position.fraction;
  return {from.x_m + t * (to.x_m - from.x_m), from.y_m + t * (to.y_m - from.y_m),
          wrap_angle(from.yaw_rad + t * next.step_turn_rad)};
}

bool WheelOdometry::pose_at(std::int64_t stamp_ns, Pose2d& T_odom_base) const {
  HistoryPosition position;
  if (!locate(stamp_ns, position)) return false;
  T_odom_base = interpolate(position);
  return true;
}

RelativeMotionStatus WheelOdometry::relative_motion(std::int64_t stamp_a_ns, std::int64_t stamp_b_ns,
                                                    RelativeMotion& motion) const {
  if (stamp_b_ns < stamp_a_ns) return RelativeMotionStatus::kWrongOrder;
  HistoryPosition a;
  HistoryPosition b;
  if (!locate(stamp_a_ns, a) || !locate(stamp_b_ns, b)) return RelativeMotionStatus::kNotInHistory;
  const Pose2d T_odom_a = interpolate(a);
  const Pose2d T_odom_b = interpolate(b);

  // The wheel noise of the steps between a and b, in the odometry frame. Each step (or the
  // part of it inside [a, b], its noise scaled by that fraction, as the noise grows with the
  // wheel travel) is propagated as the integration did: Q' = J Q Jᵀ + N with J the lever of
  // the step's displacement. Step i leads from entry i-1 to entry i.
  Eigen::Matrix3d accumulated = Eigen::Matrix3d::Zero();
  int missing_frames = 0;
  Pose2d previous = T_odom_a;
  const auto add_step = [&](std::size_t step, double portion, const Pose2d& end) {
    const HistoryEntry& entry = history(step);
    if (portion <= 0.0) return true;
    if (!entry.connected) return false;
    const Eigen::Matrix3d J = lever_jacobian(end.x_m - previous.x_m, end.y_m - previous.y_m);
    accumulated = J * accumulated * J.transpose() + portion * entry.step_noise;
    missing_frames += entry.missing_frames;
    previous = end;
    return true;
  };
  bool continuous = true;
  if (a.index == b.index) {
    if (b.fraction > a.fraction) continuous = add_step(a.index + 1, b.fraction - a.fraction, T_odom_b);
  } else {
    continuous = add_step(a.index + 1, 1.0 - a.fraction, history(a.index + 1).T_odom_base);
    for (std::size_t step = a.index + 2; continuous && step <= b.index; ++step) {
      continuous = add_step(step, 1.0, history(step).T_odom_base);
    }
    if (continuous && b.fraction > 0.0) continuous = add_step(b.index + 1, b.fraction, T_odom_b);
  }
  if (!continuous) return RelativeMotionStatus::kDiscontinuous;

  // Express it in the base frame at a: rotate the position block by −θ_a.
  Eigen::Matrix3d R_a_odom = Eigen::Matrix3d::Identity();
  const double c = std::cos(T_odom_a.yaw_rad);
  const double s = std::sin(T_odom_a.yaw_rad);
  R_a_odom(0, 0) = c;
  R_a_odom(0, 1) = s;
  R_a_odom(1, 0) = -s;
  R_a_odom(1, 1) = c;
  motion.T_a_b = compose(inverse(T_odom_a), T_odom_b);
  motion.covariance = R_a_odom * accumulated * R_a_odom.transpose();
  motion.missing_frames = missing_frames;
  return RelativeMotionStatus::kOk;
}

}  // namespace rankslam::nav
