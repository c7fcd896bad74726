#include "rankslam/nav/pose_broadcaster.hpp"

#include "rankslam/nav/pose_uncertainty.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

namespace rankslam::nav {
namespace {

std::int64_t period_ns(double rate_hz) { return static_cast<std::int64_t>(std::llround(1e9 / rate_hz)); }

bool within(double value, double min, double max) { return value >= min && value <= max; }

// The two frames one transform of a pose cycle takes.
PoseXYYaw xy_yaw_of(const PlanarPose& pose, std::uint8_t counter) {
  return {pose.x_m, pose.y_m, pose.yaw_deg, counter};
}
PoseZRollPitch z_roll_pitch_of(const PlanarPose& pose, std::uint8_t counter) {
  return {pose.z_m, pose.roll_deg, pose.pitch_deg, counter};
}

std::string out_of_range(const char* name, double value, const char* range) {
  std::ostringstream text;
  text << name << " = " << value << " is outside " << range;
  return text.str();
}

}  // namespace

std::string validate(const PoseOutputConfig& config) {
  if (!within(config.pose_rate_hz, 1.0, 200.0)) return out_of_range("pose_rate_hz", config.pose_rate_hz, "1 .. 200");
  if (!within(config.heartbeat_rate_hz, 0.5, 100.0)) return out_of_range("heartbeat_rate_hz", config.heartbeat_rate_hz, "0.5 .. 100");
  if (!within(config.watchdog_timeout_s, 0.05, 10.0)) return out_of_range("watchdog_timeout_s", config.watchdog_timeout_s, "0.05 .. 10");
  if (config.lost_after_failed_frames < 1 || config.lost_after_failed_frames > 1000) {
    return "lost_after_failed_frames = " + std::to_string(config.lost_after_failed_frames) + " is outside 1 .. 1000";
  }
  return {};
}

PoseBroadcaster::PoseBroadcaster(const PoseOutputConfig& config, hal::CanBus& bus, const hal::Clock& clock,
                                 const WheelNoise& wheel_noise)
    : config_(config),
      bus_(bus),
      clock_(clock),
      pose_period_ns_(period_ns(config.pose_rate_hz)),
      heartbeat_period_ns_(period_ns(config.heartbeat_rate_hz)),
      watchdog_ns_(static_cast<std::int64_t>(std::llround(config.watchdog_timeout_s * 1e9))),
      start_ns_(clock.now_ns()),
      next_pose_ns_(start_ns_),
      next_heartbeat_ns_(start_ns_),
      last_frame_ns_(start_ns_),
      last_heartbeat_ns_(start_ns_) {
  wheel_noise_ = wheel_noise;
}

void PoseBroadcaster::update(const PoseSample& sample) {
  T_map_odom_ = sample.map_correction * T_map_odom_;
  // Re-orthonormalised: corrections compose for as long as the robot runs.
  const Eigen::Quaterniond rotation(T_map_odom_.rotation());
  T_map_odom_.linear() = rotation.normalized().toRotationMatrix();
  latest_ = sample;
  wheel_motion_.setIdentity();
  // The velocity from the odom pose's change since the previous frame (the odom frame does not
  // jump on a correction, so neither does the velocity).
  const Eigen::Isometry3d T_odom_base_now(T_map_odom_.inverse() * sample.T_map_base);
  sample_velocity_.reset();
  if (previous_odom_) {
    const double dt_s = static_cast<double>(sample.capture_ns - previous_odom_->second) * 1e-9;
    if (dt_s > 0.0 && dt_s <= kMaxVelocityInterval_s) {
      const Eigen::Isometry3d step = previous_odom_->first.inverse() * T_odom_base_now;
      const PlanarPose change = to_planar_pose(step);
      PoseVelocity velocity;
      velocity.vx_mps = step.translation().x() / dt_s;
      velocity.vy_mps = step.translation().y() / dt_s;
      velocity.yaw_rate_dps = change.yaw_deg / dt_s;
      sample_velocity_ = velocity;
    }
  }
  previous_odom_.emplace(T_odom_base_now, sample.capture_ns);
  last_frame_ns_ = clock_.now_ns();
  consecutive_failures_ = sample.registered || sample.wheels_only ? 0 : consecutive_failures_ + 1;
  ++frames_since_heartbeat_;
}

void PoseBroadcaster::set_camera_state(bool fault, bool end_of_stream, bool wide_fault) {
  camera_fault_ = fault;
  end_of_stream_ = end_of_stream;
  wide_camera_fault_ = wide_fault;
}

bool PoseBroadcaster::watchdog_expired(std::int64_t now_ns) const { return now_ns - last_frame_ns_ > watchdog_ns_; }

PoseStatus PoseBroadcaster::status() const {
  if (watchdog_expired(clock_.now_ns())) return PoseStatus::kLost;
  if (!latest_) return PoseStatus::kInitialising;
  if (latest_->lost || consecutive_failures_ >= config_.lost_after_failed_frames) return PoseStatus::kLost;
  return latest_->registered ? PoseStatus::kTracking : PoseStatus::kDegraded;
}

void PoseBroadcaster::send(const hal::CanFrame& frame) {
  switch (bus_.send(frame)) {
    case hal::ReadStatus::kOk: return;
    case hal::ReadStatus::kNoData:
      ++counters_.tx_dropped;
      dropped_since_heartbeat_ = true;
      return;
    default:
      ++counters_.tx_faults;
      dropped_since_heartbeat_ = true;
      return;
  }
}

void PoseBroadcaster::set_wheel_motion(const Eigen::Isometry3d& T_capture_now) {
  if (config_.wheel_propagation) wheel_motion_ = T_capture_now;
}

std::optional<PoseVelocity> PoseBroadcaster::velocity() const {
  if (status() == PoseStatus::kLost) return std::nullopt;
  return sample_velocity_;
}

Eigen::Isometry3d PoseBroadcaster::T_odom_base() const {
  if (!latest_) return Eigen::Isometry3d::Identity();
  return Eigen::Isometry3d(T_map_odom_.inverse() * latest_->T_map_base * wheel_motion_);
}

void PoseBroadcaster::send_pose_cycle(std::int64_t now_ns) {
  const PoseStatus current = status();
  const PlanarPose pose = to_planar_pose(T_odom_base());
  const PlanarPose map_odom = to_planar_pose(T_map_odom_);
  PoseQuality quality;
  quality.status = current;
  quality.position_saturated = position_saturates(pose) || position_saturates(map_odom);
  quality.counter = pose_counter_;
  if (latest_) {
    quality.wheel_slip = latest_->wheel_slip;
    quality.frame_counter = static_cast<std::uint8_t>(latest_->frame_sequence & 0xFFU);
    const std::int64_t age_ms = std::max<std::int64_t>(0, (now_ns - latest_->capture_ns) / 1'000'000);
    quality.age_ms = static_cast<std::uint16_t>(std::min<std::int64_t>(age_ms, std::numeric_limits<std::uint16_t>::max()));
    quality.inlier_percent = latest_->inlier_percent;
    // Unknown stays unknown: no estimate while initialising, none worth sending when lost.
    if (current != PoseStatus::kLost && latest_->position_sigma_m && latest_->yaw_sigma_deg) {
      PoseSigmas sigmas{*latest_->position_sigma_m, *latest_->yaw_sigma_deg};
      // The wheels moved the pose on since the frame: their noise adds to it.
      const Eigen::AngleAxisd turn(wheel_motion_.rotation());
      sigmas = grown_by_wheels(sigmas, wheel_motion_.translation().head<2>().norm(), std::abs(turn.angle()),
                               wheel_noise_.wheel_variance_per_m, wheel_noise_.track_width_m);
      quality.position_sigma_m = sigmas.position_m;
      quality.yaw_sigma_deg = sigmas.yaw_deg;
    }
  }
  PoseVelocity velocity;
  if (const auto estimate = this->velocity()) velocity = *estimate;
  velocity.counter = pose_counter_;
  send(encode_pose_xy_yaw(xy_yaw_of(pose, pose_counter_), now_ns));
  send(encode_pose_z_roll_pitch(z_roll_pitch_of(pose, pose_counter_), now_ns));
  send(encode_pose_xy_yaw(xy_yaw_of(map_odom, pose_counter_), now_ns, kMapOdomXYYawId));
  send(encode_pose_z_roll_pitch(z_roll_pitch_of(map_odom, pose_counter_), now_ns, kMapOdomZRollPitchId));
  send(encode_pose_velocity(velocity, now_ns));
  send(encode_pose_quality(quality, now_ns));
  pose_counter_ = static_cast<std::uint8_t>((pose_counter_ + 1U) % kPoseCounterModulus);
  ++counters_.pose_cycles;
  if (current == PoseStatus::kLost) ++counters_.lost_cycles;
}

void PoseBroadcaster::send_heartbeat(std::int64_t now_ns) {
  Heartbeat heartbeat;
  heartbeat.uptime_ms = static_cast<std::uint32_t>(static_cast<std::uint64_t>((now_ns - start_ns_) / 1'000'000) & 0xFFFFFFFFU);
  heartbeat.status = status();
  heartbeat.camera_fault = camera_fault_;
  heartbeat.camera_watchdog = watchdog_expired(now_ns);
  heartbeat.can_tx_dropped = dropped_since_heartbeat_;
  heartbeat.end_of_stream = end_of_stream_;
  heartbeat.wide_camera_fault = wide_camera_fault_;
  const double elapsed_s = static_cast<double>(now_ns - last_heartbeat_ns_) * 1e-9;
  const double rate = elapsed_s > 0.0 ? static_cast<double>(frames_since_heartbeat_) / elapsed_s : 0.0;
  heartbeat.frames_per_s = static_cast<std::uint8_t>(std::clamp(std::round(rate), 0.0, 255.0));
  heartbeat.counter = heartbeat_counter_++;
  dropped_since_heartbeat_ = false;
  frames_since_heartbeat_ = 0;
  last_heartbeat_ns_ = now_ns;
  send(encode_heartbeat(heartbeat, now_ns));
  ++counters_.heartbeats;
}

std::int64_t PoseBroadcaster::poll() {
  const std::int64_t now_ns = clock_.now_ns();
  if (now_ns >= next_pose_ns_) {
    send_pose_cycle(now_ns);
    next_pose_ns_ += pose_period_ns_;
    // Behind by more than a period (a stalled thread): resume the schedule from now, no burst.
    if (next_pose_ns_ <= now_ns) next_pose_ns_ = now_ns + pose_period_ns_;
  }
  if (now_ns >= next_heartbeat_ns_) {
    send_heartbeat(now_ns);
    next_heartbeat_ns_ += heartbeat_period_ns_;
    if (next_heartbeat_ns_ <= now_ns) next_heartbeat_ns_ = now_ns + heartbeat_period_ns_;
  }
  return std::max<std::int64_t>(0, std::min(next_pose_ns_, next_heartbeat_ns_) - now_ns);
}

}  // namespace rankslam::nav
