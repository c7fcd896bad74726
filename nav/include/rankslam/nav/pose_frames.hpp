#pragma once

#include "rankslam/hal/messages.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string_view>

namespace rankslam::nav {

// Pose output frames rankslam sends to the base controller (deploy/can/rankslam.dbc, README
// "CAN frames"). Every frame is 8 bytes, signals little-endian (Intel) and packed from bit 0 of
// byte 0 upwards; signed signals are two's complement. One pose cycle is PoseXYYaw,
// PoseZRollPitch, MapOdomXYYaw, MapOdomZRollPitch, PoseVelocity and PoseQuality, in that order,
// all carrying the same 4-bit cycle counter; PoseQuality closes the cycle.
//
// Frames as in ROS REP 105: the pose frames carry the base in the odom frame, which moves
// continuously (a loop closure never makes it jump); the map-odom frames carry the odom frame
// in the map frame, which takes every loop-closure correction. The base in the map frame is
// T_map_base = T_map_odom * T_odom_base. Both frames start as the base frame at start-up.

inline constexpr std::uint32_t kPoseXYYawId = 0x110;
inline constexpr std::uint32_t kPoseZRollPitchId = 0x111;
inline constexpr std::uint32_t kPoseQualityId = 0x112;
inline constexpr std::uint32_t kMapOdomXYYawId = 0x113;
inline constexpr std::uint32_t kMapOdomZRollPitchId = 0x114;
inline constexpr std::uint32_t kPoseVelocityId = 0x115;
inline constexpr std::uint32_t kHeartbeatId = 0x118;
inline constexpr std::uint8_t kPoseFrameLength = 8;

/// Position resolution, metres per count, and the largest |coordinate| that fits 22 signed bits.
inline constexpr double kPositionScale_m = 0.001;
inline constexpr std::int32_t kPositionMaxCount = (1 << 21) - 1;
/// Angle resolution, degrees per count (16 signed bits).
inline constexpr double kAngleScale_deg = 0.01;
/// The cycle counter of the pose frames wraps at this value.
inline constexpr std::uint8_t kPoseCounterModulus = 16;

/// What the SLAM output is worth to the base controller.
enum class PoseStatus : std::uint8_t {
  kInitialising = 0,  ///< No camera frame processed yet; the pose is the origin.
  kTracking = 1,      ///< The latest frame was registered.
  kDegraded = 2,      ///< Registration failed; the wheels carry the pose, or it is propagated at constant velocity.
  kLost = 3,          ///< Frames stopped arriving or failed for too long; do not use the pose.
};

[[nodiscard]] constexpr std::string_view to_string(PoseStatus status) {
  switch (status) {
    case PoseStatus::kInitialising: return "initialising";
    case PoseStatus::kTracking: return "tracking";
    case PoseStatus::kDegraded: return "degraded";
    case PoseStatus::kLost: return "lost";
  }
  return "unknown";
}

/// A rigid motion (the base in the odom frame, the odom frame in the map frame) as x, y, z and
/// Z-Y-X Euler angles:
/// R = Rz(yaw) * Ry(pitch) * Rx(roll).
struct PlanarPose {
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  double roll_deg = 0.0;   ///< [-180, 180)
  double pitch_deg = 0.0;  ///< [-90, 90]
  double yaw_deg = 0.0;    ///< [-180, 180)
};

/// Euler decomposition of `T` (pitch clamped to ±90° at the singularity, roll then 0).
[[nodiscard]] PlanarPose to_planar_pose(const Eigen::Isometry3d& T);
/// The isometry `to_planar_pose` decomposed.
[[nodiscard]] Eigen::Isometry3d to_isometry(const PlanarPose& pose);

/// `PoseXYYaw` 0x110 (T_odom_base) and `MapOdomXYYaw` 0x113 (T_map_odom): bits 0..21 x (int22,
/// 1 mm), 22..43 y (int22, 1 mm), 44..59 yaw (int16, 0.01°), 60..63 cycle counter.
struct PoseXYYaw {
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_deg = 0.0;
  std::uint8_t counter = 0;  ///< 0..15
};

/// `PoseZRollPitch` 0x111 (T_odom_base) and `MapOdomZRollPitch` 0x114 (T_map_odom): bits 0..21 z
/// (int22, 1 mm), 22..37 roll (int16, 0.01°), 38..53 pitch (int16, 0.01°), 54..59 reserved (0),
/// 60..63 cycle counter.
struct PoseZRollPitch {
  double z_m = 0.0;
  double roll_deg = 0.0;
  double pitch_deg = 0.0;
  std::uint8_t counter = 0;
};

/// `PoseQuality` 0x112: byte 0 bits 0..1 status, bit 2 a position coordinate saturated at
/// ±2097.151 m, bit 3 wheel slip (vision overruled the wheels), bits 4..7 cycle counter; byte 1 low 8 bits of the camera frame number the pose
/// comes from; bytes 2..3 pose age (capture to transmission), uint16 ms, saturating; bytes 4..5
/// position standard deviation, uint16 0.1 mm, 0xFFFF = unknown; byte 6 yaw standard
/// deviation, uint8 0.02°, 0xFF = unknown; byte 7 inlier ratio of the registration, uint8
/// percent 0..100, 0xFF = unknown.
struct PoseQuality {
  PoseStatus status = PoseStatus::kInitialising;
  bool position_saturated = false;
  /// Vision overruled the wheels on the frame the pose comes from: a wheel slipped, or the base
  /// moved without its wheels (bit 3).
  bool wheel_slip = false;
  std::uint8_t counter = 0;
  std::uint8_t frame_counter = 0;
  std::uint16_t age_ms = 0;
  std::optional<double> position_sigma_m;  ///< nullopt = unknown
  std::optional<double> yaw_sigma_deg;     ///< nullopt = unknown
  std::optional<std::uint8_t> inlier_percent;
};

/// Velocity resolution, m/s per count, and yaw-rate resolution, °/s per count (16 signed bits);
/// the raw value kVelocityUnknown (-32768) of each signal means unknown.
inline constexpr double kVelocityScale_mps = 0.001;
inline constexpr double kYawRateScale_dps = 0.01;
inline constexpr std::int32_t kVelocityUnknown = -32768;

/// `PoseVelocity` 0x115: the base's velocity in its own frame (x forward, y left), from the
/// odom pose's change between camera frames. Bits 0..15 vx (int16, 1 mm/s), 16..31 vy (int16,
/// 1 mm/s), 32..47 yaw rate (int16, 0.01°/s), 48..59 reserved (0), 60..63 cycle counter; each
/// signal saturates at ±32767 counts, and -32768 is unknown.
struct PoseVelocity {
  std::optional<double> vx_mps;        ///< nullopt = unknown
  std::optional<double> vy_mps;        ///< nullopt = unknown
  std::optional<double> yaw_rate_dps;  ///< nullopt = unknown
  std::uint8_t counter = 0;
};

/// `Heartbeat` 0x118: bytes 0..3 uptime, uint32 ms (wraps after 49.7 days); byte 4 bits 0..1
/// status (as PoseQuality); byte 5 fault bits: 0 camera fault, 1 camera watchdog expired,
/// 2 CAN frames dropped since the last heartbeat, 3 camera end of stream (replay only), 4 the
/// wide-angle camera faulted or went silent (the SLAM goes on with the RGB-D camera alone);
/// byte 6 camera frames processed in the last second, uint8 saturating; byte 7 rolling counter.
struct Heartbeat {
  std::uint32_t uptime_ms = 0;
  PoseStatus status = PoseStatus::kInitialising;
  bool camera_fault = false;
  bool camera_watchdog = false;
  bool can_tx_dropped = false;
  bool end_of_stream = false;
  bool wide_camera_fault = false;
  std::uint8_t frames_per_s = 0;
  std::uint8_t counter = 0;
};

/// Encoders quantise to the nearest count; angles are wrapped into their range first, positions
/// saturate at ±kPositionMaxCount (PoseQuality::position_saturated tells).
/// `id` is kPoseXYYawId or kMapOdomXYYawId (kPoseZRollPitchId or kMapOdomZRollPitchId): the same
/// layout for both transforms.
[[nodiscard]] hal::CanFrame encode_pose_xy_yaw(const PoseXYYaw& pose, std::int64_t stamp_ns,
                                               std::uint32_t id = kPoseXYYawId);
[[nodiscard]] hal::CanFrame encode_pose_z_roll_pitch(const PoseZRollPitch& pose, std::int64_t stamp_ns,
                                                     std::uint32_t id = kPoseZRollPitchId);
[[nodiscard]] hal::CanFrame encode_pose_quality(const PoseQuality& quality, std::int64_t stamp_ns);
[[nodiscard]] hal::CanFrame encode_pose_velocity(const PoseVelocity& velocity, std::int64_t stamp_ns);
[[nodiscard]] hal::CanFrame encode_heartbeat(const Heartbeat& heartbeat, std::int64_t stamp_ns);

/// Decoders: nullopt when the identifier, length or an enum value is wrong.
[[nodiscard]] std::optional<PoseXYYaw> decode_pose_xy_yaw(const hal::CanFrame& frame,
                                                         std::uint32_t id = kPoseXYYawId);
[[nodiscard]] std::optional<PoseZRollPitch> decode_pose_z_roll_pitch(const hal::CanFrame& frame,
                                                                     std::uint32_t id = kPoseZRollPitchId);
[[nodiscard]] std::optional<PoseQuality> decode_pose_quality(const hal::CanFrame& frame);
[[nodiscard]] std::optional<PoseVelocity> decode_pose_velocity(const hal::CanFrame& frame);
[[nodiscard]] std::optional<Heartbeat> decode_heartbeat(const hal::CanFrame& frame);

/// True when some coordinate of `pose` does not fit the 22-bit position signals.
[[nodiscard]] bool position_saturates(const PlanarPose& pose);

}  // namespace rankslam::nav
