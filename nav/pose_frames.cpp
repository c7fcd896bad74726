#include "rankslam/nav/pose_frames.hpp"
#include "rankslam/core/units.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace rankslam::nav {
namespace {


// Signals are laid out in one little-endian 64-bit word: bit n of the frame is bit n % 8 of
// byte n / 8 (DBC "@1", Intel order).
std::uint64_t load_word(const hal::CanFrame& frame) {
  std::uint64_t word = 0;
  for (std::size_t i = 0; i < 8; ++i) word |= static_cast<std::uint64_t>(frame.data[i]) << (8U * i);
  return word;
}

hal::CanFrame store_word(std::uint64_t word, std::uint32_t id, std::int64_t stamp_ns) {
  hal::CanFrame frame;
  frame.stamp_ns = stamp_ns;
  frame.id = id;
  frame.length = kPoseFrameLength;
  for (std::size_t i = 0; i < 8; ++i) frame.data[i] = static_cast<std::uint8_t>((word >> (8U * i)) & 0xFFU);
  return frame;
}

std::uint64_t mask(unsigned bits) { return bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1; }

void put_unsigned(std::uint64_t& word, unsigned start, unsigned bits, std::uint64_t value) {
  word |= (value & mask(bits)) << start;
}

void put_signed(std::uint64_t& word, unsigned start, unsigned bits, std::int64_t value) {
  put_unsigned(word, start, bits, static_cast<std::uint64_t>(value));
}

std::uint64_t get_unsigned(std::uint64_t word, unsigned start, unsigned bits) { return (word >> start) & mask(bits); }

std::int64_t get_signed(std::uint64_t word, unsigned start, unsigned bits) {
  const std::uint64_t raw = get_unsigned(word, start, bits);
  const std::uint64_t sign = std::uint64_t{1} << (bits - 1);
  return static_cast<std::int64_t>(raw ^ sign) - static_cast<std::int64_t>(sign);
}

std::int64_t position_count(double value_m) {
  if (!std::isfinite(value_m)) return 0;
  const double count = std::round(value_m / kPositionScale_m);
  return static_cast<std::int64_t>(std::clamp(count, -static_cast<double>(kPositionMaxCount),
                                              static_cast<double>(kPositionMaxCount)));
}

/// Wraps into [-180, 180) and quantises; the result always fits int16.
std::int64_t wrapped_angle_count(double angle_deg) {
  if (!std::isfinite(angle_deg)) return 0;
  constexpr std::int64_t kFullTurn = 36000;
  auto count = static_cast<std::int64_t>(std::round(std::fmod(angle_deg, 360.0) / kAngleScale_deg));
  count = ((count + kFullTurn / 2) % kFullTurn + kFullTurn) % kFullTurn - kFullTurn / 2;
  return count;
}

std::int64_t pitch_count(double pitch_deg) {
  if (!std::isfinite(pitch_deg)) return 0;
  return static_cast<std::int64_t>(std::round(std::clamp(pitch_deg, -90.0, 90.0) / kAngleScale_deg));
}

bool valid(const hal::CanFrame& frame, std::uint32_t id) {
  return frame.id == id && !frame.extended && frame.length == kPoseFrameLength;
}

std::uint64_t saturate(double value, double scale, std::uint64_t unknown) {
  if (!std::isfinite(value) || value < 0.0) return unknown;
  const double count = std::round(value / scale);
  return count >= static_cast<double>(unknown - 1) ? unknown - 1 : static_cast<std::uint64_t>(count);
}

/// A velocity signal: quantised, saturating at ±32767 counts; unknown (and not finite) is -32768.
std::int64_t velocity_count(const std::optional<double>& value, double scale) {
  if (!value || !std::isfinite(*value)) return kVelocityUnknown;
  return static_cast<std::int64_t>(std::clamp(std::round(*value / scale), -32767.0, 32767.0));
}

std::optional<double> velocity_value(std::int64_t count, double scale) {
  if (count == kVelocityUnknown) return std::nullopt;
  return static_cast<double>(count) * scale;
}

}  // namespace

PlanarPose to_planar_pose(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.linear();
  PlanarPose pose;
  pose.x_m = T.translation().x();
  pose.y_m = T.translation().y();
  pose.z_m = T.translation().z();
  const double sin_pitch = std::clamp(-R(2, 0), -1.0, 1.0);
  pose.pitch_deg = rad_to_deg(std::asin(sin_pitch));
  if (std::abs(sin_pitch) < 1.0 - 1e-12) {
    pose.yaw_deg = rad_to_deg(std::atan2(R(1, 0), R(0, 0)));
    pose.roll_deg = rad_to_deg(std::atan2(R(2, 1), R(2, 2)));
  } else {
    // Gimbal lock: only yaw - roll (or yaw + roll) is defined; put it all into yaw.
    pose.yaw_deg = rad_to_deg(std::atan2(-R(0, 1), R(1, 1)));
    pose.roll_deg = 0.0;
  }
  return pose;
}

Eigen::Isometry3d to_isometry(const PlanarPose& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(deg_to_rad(pose.yaw_deg), Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(deg_to_rad(pose.pitch_deg), Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(deg_to_rad(pose.roll_deg), Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(pose.x_m, pose.y_m, pose.z_m);
  return T;
}

bool position_saturates(const PlanarPose& pose) {
  const double limit_m = static_cast<double>(kPositionMaxCount) * kPositionScale_m;
  return !(std::abs(pose.x_m) <= limit_m && std::abs(pose.y_m) <= limit_m && std::abs(pose.z_m) <= limit_m);
}

hal::CanFrame encode_pose_xy_yaw(const PoseXYYaw& pose, std::int64_t stamp_ns, std::uint32_t id) {
  std::uint64_t word = 0;
  put_signed(word, 0, 22, position_count(pose.x_m));
  put_signed(word, 22, 22, position_count(pose.y_m));
  put_signed(word, 44, 16, wrapped_angle_count(pose.yaw_deg));
  put_unsigned(word, 60, 4, pose.counter);
  return store_word(word, id, stamp_ns);
}

hal::CanFrame encode_pose_z_roll_pitch(const PoseZRollPitch& pose, std::int64_t stamp_ns, std::uint32_t id) {
  std::uint64_t word = 0;
  put_signed(word, 0, 22, position_count(pose.z_m));
  put_signed(word, 22, 16, wrapped_angle_count(pose.roll_deg));
  put_signed(word, 38, 16, pitch_count(pose.pitch_deg));
  put_unsigned(word, 60, 4, pose.counter);
  return store_word(word, id, stamp_ns);
}

hal::CanFrame encode_pose_quality(const PoseQuality& quality, std::int64_t stamp_ns) {
  std::uint64_t word = 0;
  put_unsigned(word, 0, 2, static_cast<std::uint8_t>(quality.status));
  put_unsigned(word, 2, 1, quality.position_saturated ? 1U : 0U);
  put_unsigned(word, 3, 1, quality.wheel_slip ? 1U : 0U);
  put_unsigned(word, 4, 4, quality.counter);
  put_unsigned(word, 8, 8, quality.frame_counter);
  put_unsigned(word, 16, 16, quality.age_ms);
  put_unsigned(word, 32, 16, quality.position_sigma_m ? saturate(*quality.position_sigma_m, 1e-4, 0xFFFF) : 0xFFFFU);
  put_unsigned(word, 48, 8, quality.yaw_sigma_deg ? saturate(*quality.yaw_sigma_deg, 0.02, 0xFF) : 0xFFU);
  put_unsigned(word, 56, 8, quality.inlier_percent ? std::min<std::uint8_t>(*quality.inlier_percent, 100) : 0xFFU);
  return store_word(word, kPoseQualityId, stamp_ns);
}

hal::CanFrame encode_pose_velocity(const PoseVelocity& velocity, std::int64_t stamp_ns) {
  std::uint64_t word = 0;
  put_signed(word, 0, 16, velocity_count(velocity.vx_mps, kVelocityScale_mps));
  put_signed(word, 16, 16, velocity_count(velocity.vy_mps, kVelocityScale_mps));
  put_signed(word, 32, 16, velocity_count(velocity.yaw_rate_dps, kYawRateScale_dps));
  put_unsigned(word, 60, 4, velocity.counter);
  return store_word(word, kPoseVelocityId, stamp_ns);
}

hal::CanFrame encode_heartbeat(const Heartbeat& heartbeat, std::int64_t stamp_ns) {
  std::uint64_t word = 0;
  put_unsigned(word, 0, 32, heartbeat.uptime_ms);
  put_unsigned(word, 32, 2, static_cast<std::uint8_t>(heartbeat.status));
  put_unsigned(word, 40, 1, heartbeat.camera_fault ? 1U : 0U);
  put_unsigned(word, 41, 1, heartbeat.camera_watchdog ? 1U : 0U);
  put_unsigned(word, 42, 1, heartbeat.can_tx_dropped ? 1U : 0U);
  put_unsigned(word, 43, 1, heartbeat.end_of_stream ? 1U : 0U);
  put_unsigned(word, 44, 1, heartbeat.wide_camera_fault ? 1U : 0U);
  put_unsigned(word, 48, 8, heartbeat.frames_per_s);
  put_unsigned(word, 56, 8, heartbeat.counter);
  return store_word(word, kHeartbeatId, stamp_ns);
}

std::optional<PoseXYYaw> decode_pose_xy_yaw(const hal::CanFrame& frame, std::uint32_t id) {
  if (!valid(frame, id)) return std::nullopt;
  const std::uint64_t word = load_word(frame);
  PoseXYYaw pose;
  pose.x_m = static_cast<double>(get_signed(word, 0, 22)) * kPositionScale_m;
  pose.y_m = static_cast<double>(get_signed(word, 22, 22)) * kPositionScale_m;
  pose.yaw_deg = static_cast<double>(get_signed(word, 44, 16)) * kAngleScale_deg;
  pose.counter = static_cast<std::uint8_t>(get_unsigned(word, 60, 4));
  return pose;
}

std::optional<PoseZRollPitch> decode_pose_z_roll_pitch(const hal::CanFrame& frame, std::uint32_t id) {
  if (!valid(frame, id)) return std::nullopt;
  const std::uint64_t word = load_word(frame);
  PoseZRollPitch pose;
  pose.z_m = static_cast<double>(get_signed(word, 0, 22)) * kPositionScale_m;
  pose.roll_deg = static_cast<double>(get_signed(word, 22, 16)) * kAngleScale_deg;
  pose.pitch_deg = static_cast<double>(get_signed(word, 38, 16)) * kAngleScale_deg;
  pose.counter = static_cast<std::uint8_t>(get_unsigned(word, 60, 4));
  if (std::abs(pose.pitch_deg) > 90.0) return std::nullopt;
  return pose;
}

std::optional<PoseQuality> decode_pose_quality(const hal::CanFrame& frame) {
  if (!valid(frame, kPoseQualityId)) return std::nullopt;
  const std::uint64_t word = load_word(frame);
  PoseQuality quality;
  quality.status = static_cast<PoseStatus>(get_unsigned(word, 0, 2));
  quality.position_saturated = get_unsigned(word, 2, 1) != 0;
  quality.wheel_slip = get_unsigned(word, 3, 1) != 0;
  quality.counter = static_cast<std::uint8_t>(get_unsigned(word, 4, 4));
  quality.frame_counter = static_cast<std::uint8_t>(get_unsigned(word, 8, 8));
  quality.age_ms = static_cast<std::uint16_t>(get_unsigned(word, 16, 16));
  if (const auto sigma = get_unsigned(word, 32, 16); sigma != 0xFFFF) quality.position_sigma_m = static_cast<double>(sigma) * 1e-4;
  if (const auto sigma = get_unsigned(word, 48, 8); sigma != 0xFF) quality.yaw_sigma_deg = static_cast<double>(sigma) * 0.02;
  if (const auto ratio = get_unsigned(word, 56, 8); ratio != 0xFF) {
    if (ratio > 100) return std::nullopt;
    quality.inlier_percent = static_cast<std::uint8_t>(ratio);
  }
  return quality;
}

std::optional<PoseVelocity> decode_pose_velocity(const hal::CanFrame& frame) {
  if (!valid(frame, kPoseVelocityId)) return std::nullopt;
  const std::uint64_t word = load_word(frame);
  PoseVelocity velocity;
  velocity.vx_mps = velocity_value(get_signed(word, 0, 16), kVelocityScale_mps);
  velocity.vy_mps = velocity_value(get_signed(word, 16, 16), kVelocityScale_mps);
  velocity.yaw_rate_dps = velocity_value(get_signed(word, 32, 16), kYawRateScale_dps);
  velocity.counter = static_cast<std::uint8_t>(get_unsigned(word, 60, 4));
  return velocity;
}

std::optional<Heartbeat> decode_heartbeat(const hal::CanFrame& frame) {
  if (!valid(frame, kHeartbeatId)) return std::nullopt;
  const std::uint64_t word = load_word(frame);
  Heartbeat heartbeat;
  heartbeat.uptime_ms = static_cast<std::uint32_t>(get_unsigned(word, 0, 32));
  heartbeat.status = static_cast<PoseStatus>(get_unsigned(word, 32, 2));
  heartbeat.camera_fault = get_unsigned(word, 40, 1) != 0;
  heartbeat.camera_watchdog = get_unsigned(word, 41, 1) != 0;
  heartbeat.can_tx_dropped = get_unsigned(word, 42, 1) != 0;
  heartbeat.end_of_stream = get_unsigned(word, 43, 1) != 0;
  heartbeat.wide_camera_fault = get_unsigned(word, 44, 1) != 0;
  heartbeat.frames_per_s = static_cast<std::uint8_t>(get_unsigned(word, 48, 8));
  heartbeat.counter = static_cast<std::uint8_t>(get_unsigned(word, 56, 8));
  return heartbeat;
}

}  // namespace rankslam::nav
