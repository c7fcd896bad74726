#pragma once

#include "rankslam/hal/interfaces.hpp"
#include "rankslam/nav/pose_frames.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <utility>

namespace rankslam::nav {

/// Rates and watchdog of the pose output; fixed after construction.
struct PoseOutputConfig {
  double pose_rate_hz = 50.0;        ///< Hz; pose cycles (six frames, PoseXYYaw .. PoseQuality) per second, 1 .. 200
  double heartbeat_rate_hz = 10.0;   ///< Hz; Heartbeat frames per second, 0.5 .. 100
  double watchdog_timeout_s = 0.5;   ///< s; no camera frame for this long reports LOST, 0.05 .. 10
  int lost_after_failed_frames = 15; ///< consecutive failed registrations that report LOST, 1 .. 1000
  /// Between camera frames, move the latest SLAM pose on by the wheel odometry since the frame's
  /// capture (set_wheel_motion); false re-sends the SLAM pose unchanged.
  bool wheel_propagation = true;
};

/// Range check naming the offending field; empty when `config` is valid.
[[nodiscard]] std::string validate(const PoseOutputConfig& config);

/// The SLAM result of one camera frame, as the output needs it.
struct PoseSample {
  Eigen::Isometry3d T_map_base = Eigen::Isometry3d::Identity();
  /// The corrections of the map frame since the previous sample (a pose-graph solve applied by
  /// the SLAM loop: T_map_new_map_old, in base frames), identity when there was none. The odom
  /// frame takes them (REP 105), so the base's odom pose does not jump.
  Eigen::Isometry3d map_correction = Eigen::Isometry3d::Identity();
  std::int64_t capture_ns = 0;          ///< capture time on the broadcaster's clock
  std::uint32_t frame_sequence = 0;     ///< camera frame number
  bool registered = true;               ///< false: registration failed, pose propagated
  /// With registered false: the wheel odometry carries the pose. DEGRADED for as long as it
  /// lasts; such frames do not count towards lost_after_failed_frames.
  bool wheels_only = false;
  /// The pose is not in the map's frame (a loaded map not found yet): LOST at once.
  bool lost = false;
  /// Vision overruled the wheels on this frame (slip); PoseQuality.WheelSlip.
  bool wheel_slip = false;
  std::optional<std::uint8_t> inlier_percent;
  /// Standard deviations of the odom pose at the frame (nav::pose_sigmas of the SLAM loop's
  /// covariance since the first frame); none = unknown.
  std::optional<double> position_sigma_m;
  std::optional<double> yaw_sigma_deg;
};

/// Wheel noise the sigmas grow by while the wheels move the pose on between camera frames
/// (nav::grown_by_wheels); a zero variance leaves them as the frame's.
struct WheelNoise {
  double wheel_variance_per_m = 0.0;  ///< m²/m, WheelOdometryConfig::wheel_variance_per_m
  double track_width_m = 0.30;
};

/// Counters for the run report.
struct PoseOutputCounters {
  std::uint64_t pose_cycles = 0;    ///< pose cycles sent (six frames each)
  std::uint64_t heartbeats = 0;
  std::uint64_t lost_cycles = 0;    ///< pose cycles sent with status LOST
  std::uint64_t tx_dropped = 0;     ///< frames the bus refused because its queue was full
  std::uint64_t tx_faults = 0;      ///< frames not sent because the bus was down or gone
};

/// Sends the latest pose at a fixed rate and a heartbeat at another, on one hal::CanBus, timed
/// by a hal::Clock. The pose goes out split as in ROS REP 105: the base in a continuous odom
/// frame, and the odom frame in the map frame, which takes the loop-closure corrections. The
/// camera watchdog runs here, in the sender, so a stalled SLAM loop or camera still produces
/// heartbeats and the pose status turns LOST. Not thread-safe: one thread
/// calls everything (the application hands samples over under its own lock). Never allocates.
class PoseBroadcaster {
 public:
  PoseBroadcaster(const PoseOutputConfig& config, hal::CanBus& bus, const hal::Clock& clock,
                  const WheelNoise& wheel_noise = {});

  /// A camera frame was processed; its arrival (now) feeds the watchdog. The wheel motion since
  /// the frame starts at identity.
  void update(const PoseSample& sample);
  /// The base's motion since the latest sample's capture by the wheel odometry (T_base(capture)
  /// _base(now)); with wheel_propagation the pose cycles send the sample's pose moved by it.
  void set_wheel_motion(const Eigen::Isometry3d& T_capture_now);
  /// Camera state for the heartbeat's fault bits.
  void set_camera_state(bool fault, bool end_of_stream, bool wide_fault = false);
  /// Sends every frame that is due now. Returns the time until the next one is due, ns.
  [[nodiscard]] std::int64_t poll();

  /// The status the next pose cycle will carry.
  [[nodiscard]] PoseStatus status() const;
  /// The base in the odom frame and the odom frame in the map frame, as the next cycle sends
  /// them (T_map_base = T_map_odom * T_odom_base).
  [[nodiscard]] Eigen::Isometry3d T_odom_base() const;
  [[nodiscard]] const Eigen::Isometry3d& T_map_odom() const { return T_map_odom_; }
  /// The base's velocity in its own frame the next cycle sends (PoseVelocity): the odom pose's
  /// change between the last two camera frames, over their capture interval. None before the
  /// second frame, when the interval is not in (0, kMaxVelocityInterval_s], and when LOST.
  [[nodiscard]] std::optional<PoseVelocity> velocity() const;
  /// Longest capture interval a velocity is computed over, s.
  static constexpr double kMaxVelocityInterval_s = 0.5;
  [[nodiscard]] const PoseOutputCounters& counters() const { return counters_; }

 private:
  void send(const hal::CanFrame& frame);
  void send_pose_cycle(std::int64_t now_ns);
  void send_heartbeat(std::int64_t now_ns);
  [[nodiscard]] bool watchdog_expired(std::int64_t now_ns) const;

  PoseOutputConfig config_;
  hal::CanBus& bus_;
  const hal::Clock& clock_;
  std::int64_t pose_period_ns_;
  std::int64_t heartbeat_period_ns_;
  std::int64_t watchdog_ns_;
  std::int64_t start_ns_;
  std::int64_t next_pose_ns_;
  std::int64_t next_heartbeat_ns_;
  std::int64_t last_frame_ns_;
  std::optional<PoseSample> latest_;
  Eigen::Isometry3d T_map_odom_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d wheel_motion_ = Eigen::Isometry3d::Identity();
  WheelNoise wheel_noise_;
  /// The previous sample's odom pose and capture time, and the velocity between it and the latest.
  std::optional<std::pair<Eigen::Isometry3d, std::int64_t>> previous_odom_;
  std::optional<PoseVelocity> sample_velocity_;
  int consecutive_failures_ = 0;
  std::uint8_t pose_counter_ = 0;
  std::uint8_t heartbeat_counter_ = 0;
  std::uint32_t frames_since_heartbeat_ = 0;
  std::int64_t last_heartbeat_ns_;
  bool dropped_since_heartbeat_ = false;
  bool camera_fault_ = false;
  bool end_of_stream_ = false;
  bool wide_camera_fault_ = false;
  PoseOutputCounters counters_;
};

}  // namespace rankslam::nav
