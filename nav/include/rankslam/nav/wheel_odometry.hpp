#pragma once

#include "rankslam/core/units.hpp"
#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/nav/wheel_frame.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rankslam::nav {

/// A rigid motion in the floor plane: frame B in frame A (x forward, y left, yaw about z,
/// counter-clockwise positive).
struct Pose2d {
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;  ///< [-π, π)
};

/// T_a_c = T_a_b ⊕ T_b_c.
[[nodiscard]] Pose2d compose(const Pose2d& T_a_b, const Pose2d& T_b_c);
/// T_b_a from T_a_b.
[[nodiscard]] Pose2d inverse(const Pose2d& T_a_b);
/// The planar pose as a 3D rigid motion (z = 0, rotation about z).
[[nodiscard]] Eigen::Isometry3d to_isometry3d(const Pose2d& pose);

/// Tuning of the wheel odometry; the wheel geometry itself comes from the calibration
/// (hal::WheelGeometry). Fixed after construction.
struct WheelOdometryConfig {
  /// m/s; a wheel whose counter moved faster than this between two frames is a corrupted or
  /// re-based counter, not motion: the frame is rejected. 0.1 .. 20.
  double max_wheel_speed_mps = 2.0;
  /// s; a stamp step larger than this resets the integration baseline: the arc model cannot
  /// stand for an unknown path over a long interval. Below 128 frame periods, so the 8-bit
  /// rolling counter still counts the missing frames. 0.02 .. 1.
  double max_frame_gap_s = 0.25;
  /// m²/m; variance of one wheel's travel per metre it rolled (the per-wheel model of
  /// Siegwart & Nourbakhsh, "Introduction to Autonomous Mobile Robots", 5.2.4: Σ_Δ =
  /// diag(k|Δs_r|, k|Δs_l|)). The default, 1e-4, is a 1 cm standard deviation after 1 m. 0 .. 1.
  double wheel_variance_per_m = 1e-4;
  /// Poses kept for relative_motion(); at 100 Hz the default holds 10.24 s. 2 .. 1'000'000.
  int history_capacity = 1024;

  /// Calls visit(name, field, min, max, unit, doc) for every parameter (the ranges validate()
  /// checks), for the `wheel_odometry:` section of the YAML configuration.
  template <class V>
  void visit_parameters(V&& visit) {
    visit("max_wheel_speed_mps", max_wheel_speed_mps, 0.1, 20.0, "m/s",
          "a wheel faster than this between two frames is a corrupted counter: the frame is rejected");
    visit("max_frame_gap_s", max_frame_gap_s, 0.02, 1.0, "s",
          "a larger stamp step starts a new integration baseline");
    visit("wheel_variance_per_m", wheel_variance_per_m, 0.0, 1.0, "m^2/m",
          "variance of one wheel's travel per metre rolled (1e-4: 1 cm after 1 m)");
    visit("history_capacity", history_capacity, 2, 1'000'000, "", "odometry poses kept for the per-frame prior");
  }
};

/// Range check naming the offending field of `config` or `wheels`; empty when both are valid.
[[nodiscard]] std::string validate(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels);

/// What one frame did to the odometry.
enum class WheelFrameResult : std::uint8_t {
  kBaseline,             ///< First frame, or the first good one after an encoder fault: counters noted, no motion.
  kIntegrated,           ///< The next frame in sequence: its tick delta moved the pose.
  kIntegratedAcrossGap,  ///< Rolling counter skipped frames: the total tick delta over the gap was integrated.
  kTimestampJump,        ///< Stamp went backwards while the rolling counter went on, or stepped over
                         ///< max_frame_gap_s: new baseline, pose kept.
  kCountersRebased,      ///< Two frames agreed with each other but not with the baseline (the controller
                         ///< restarted its counters): new baseline, pose kept.
  kDuplicate,            ///< Same stamp, or same rolling counter, as the last frame: ignored.
  kOutOfOrder,           ///< Older stamp than the last frame, rolling counter not ahead: dropped.
  kImplausible,          ///< A wheel would have moved faster than max_wheel_speed_mps: rejected.
  kEncoderFault,         ///< The controller flagged an encoder fault: dropped, next good frame re-baselines.
  kNotWheelFrame,        ///< update(CanFrame) with another identifier: ignored, not counted.
  kMalformed,            ///< update(CanFrame) with the wheel identifier but a wrong length: dropped.
};

/// Human-readable name of `result` ("integrated", "duplicate", ...).
[[nodiscard]] const char* to_string(WheelFrameResult result);

/// Every frame the odometry was handed, by what happened to it.
struct WheelOdometryStats {
  std::uint64_t frames_received = 0;     ///< WheelTicks frames handed in (malformed ones included)
  std::uint64_t frames_integrated = 0;   ///< moved the pose (across a gap or not)
  std::uint64_t gaps = 0;                ///< integrations that bridged missing frames
  std::uint64_t frames_missing = 0;      ///< frames the rolling counter says never arrived
  std::uint64_t rolling_counter_jumps = 0;  ///< newer stamp, rolling counter behind: integrated, gap unknown
  std::uint64_t duplicates = 0;
  std::uint64_t out_of_order = 0;
  std::uint64_t timestamp_jumps_backward = 0;
  std::uint64_t timestamp_jumps_forward = 0;  ///< stamp steps beyond max_frame_gap_s
  std::uint64_t implausible = 0;
  std::uint64_t counter_rebases = 0;
  std::uint64_t encoder_faults = 0;
  std::uint64_t malformed = 0;
};

/// The integrated odometry at the last frame that moved it.
struct WheelOdometryState {
  bool initialised = false;  ///< a baseline frame has been seen
  std::int64_t stamp_ns = 0;  ///< stamp of the last accepted frame
  Pose2d T_odom_base;  ///< base in the odometry frame (the base at the first frame)
  double linear_velocity_mps = 0.0;   ///< over the last integrated step; 0 after a reset
  double angular_velocity_rps = 0.0;  ///< over the last integrated step; 0 after a reset
  /// Covariance of (x_m, y_m, yaw_rad) of T_odom_base, in the odometry frame.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double distance_m = 0.0;  ///< path length of the base origin
  double turned_rad = 0.0;  ///< sum of |yaw change|
};

/// The motion of the base between two stamps.
struct RelativeMotion {
  Pose2d T_a_b;  ///< base at stamp b in the base frame at stamp a
  /// Covariance of (x_m, y_m, yaw_rad) of T_a_b, expressed in the base frame at a.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  int missing_frames = 0;  ///< frames lost inside the interval (the motion over them was bridged)
};

enum class RelativeMotionStatus : std::uint8_t {
  kOk,
  kNotInHistory,   ///< a stamp is older than the oldest or newer than the newest pose kept
  kDiscontinuous,  ///< a baseline reset lies between the stamps: the motion over it is unknown
  kWrongOrder,     ///< stamp_b_ns < stamp_a_ns
};

[[nodiscard]] const char* to_string(RelativeMotionStatus status);

/// Differential-drive odometry from the base controller's WheelTicks frames.
///
/// Each accepted frame advances the pose along the exact circular arc the two wheels' travels
/// describe (Δs = (Δs_r + Δs_l)/2, Δθ = (Δs_r − Δs_l)/b, chord Δs·sin(Δθ/2)/(Δθ/2) at heading
/// θ + Δθ/2), and the covariance by first-order propagation of the per-wheel noise model
/// through the step's Jacobians, so it grows with distance and with turning.
///
/// Poses are kept in a ring buffer sized at construction; relative_motion() interpolates in it.
/// Nothing allocates after construction. Not thread-safe: one thread calls everything.
class WheelOdometry {
 public:
  /// `config` and `wheels` must pass validate(); the history is allocated here.
  WheelOdometry(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels);

  /// One decoded frame with its monotonic stamp.
  WheelFrameResult update(const WheelTicks& ticks, std::int64_t stamp_ns);
  /// One CAN frame as received: frames with another identifier are ignored (kNotWheelFrame),
  /// the wheel identifier with a wrong length is counted as malformed.
  WheelFrameResult update(const hal::CanFrame& frame);

  [[nodiscard]] const WheelOdometryState& state() const { return state_; }
  [[nodiscard]] const WheelOdometryStats& stats() const { return stats_; }
  [[nodiscard]] const WheelOdometryConfig& config() const { return config_; }

  /// Motion of the base from stamp_a_ns to stamp_b_ns (stamp_a_ns <= stamp_b_ns), poses
  /// interpolated linearly between the kept frames, covariance of the wheel noise accumulated
  /// over the interval alone (independent of the uncertainty at stamp a).
  [[nodiscard]] RelativeMotionStatus relative_motion(std::int64_t stamp_a_ns, std::int64_t stamp_b_ns,
                                                     RelativeMotion& motion) const;
  /// Base pose at `stamp_ns`, interpolated in the history; false when it is not covered.
  [[nodiscard]] bool pose_at(std::int64_t stamp_ns, Pose2d& T_odom_base) const;

  [[nodiscard]] std::size_t history_size() const { return history_size_; }
  /// Stamps the history covers; only meaningful when history_size() > 0.
  [[nodiscard]] std::int64_t oldest_stamp_ns() const;
  [[nodiscard]] std::int64_t newest_stamp_ns() const;

 private:
  struct CounterFrame {
    WheelTicks ticks;
    std::int64_t stamp_ns = 0;
  };
  /// One kept pose and the step that led to it from the previous one.
  struct HistoryEntry {
    std::int64_t stamp_ns = 0;
    Pose2d T_odom_base;
    /// Wheel noise the step added, in the odometry frame (the step's G Σ_Δ Gᵀ).
    Eigen::Matrix3d step_noise = Eigen::Matrix3d::Zero();
    double step_turn_rad = 0.0;  ///< unwrapped yaw change of the step, for interpolation
    bool connected = false;  ///< false: a baseline reset, the motion since the previous entry is unknown
    std::uint16_t missing_frames = 0;
  };
  /// Where a stamp falls: between entry `index` and the next, `fraction` of the way.
  struct HistoryPosition {
    std::size_t index = 0;
    double fraction = 0.0;
  };

  void start_baseline(const WheelTicks& ticks, std::int64_t stamp_ns);
  [[nodiscard]] bool plausible(const CounterFrame& from, const WheelTicks& to, std::int64_t stamp_ns) const;
  void integrate(const WheelTicks& ticks, std::int64_t stamp_ns, int missing_frames);
  void push_history(const HistoryEntry& entry);
  [[nodiscard]] const HistoryEntry& history(std::size_t logical_index) const;
  [[nodiscard]] bool locate(std::int64_t stamp_ns, HistoryPosition& position) const;
  [[nodiscard]] Pose2d interpolate(const HistoryPosition& position) const;

  WheelOdometryConfig config_;
  hal::WheelGeometry wheels_;
  double metres_per_tick_;
  WheelOdometryStats stats_;
  WheelOdometryState state_;
  bool have_baseline_ = false;
  CounterFrame baseline_;            // counters the next delta is taken from
  CounterFrame last_seen_;           // last in-sequence frame, accepted or rejected: ordering and duplicates
  bool have_rejected_ = false;
  CounterFrame rejected_;            // last implausible frame, to recognise re-based counters
  std::vector<HistoryEntry> history_;  // ring buffer, sized once
  std::size_t history_head_ = 0;
  std::size_t history_size_ = 0;
};

}  // namespace rankslam::nav
