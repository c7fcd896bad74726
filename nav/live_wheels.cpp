#include "rankslam/nav/live_wheels.hpp"

namespace rankslam::nav {

void LiveWheels::enable(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels,
                        const Eigen::Isometry3d& T_base_cam, const std::vector<hal::CanFrame>* recorded) {
  std::lock_guard lock(mutex_);
  prior_.emplace(config, wheels, T_base_cam);
  recorded_ = recorded;
  next_recorded_ = 0;
}

void LiveWheels::mark_receiving() {
  {
    std::lock_guard lock(mutex_);
    receiving_ = true;
  }
  advanced_.notify_all();
}

bool LiveWheels::wait_receiving(std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  return advanced_.wait_for(lock, wait, [&] { return receiving_; });
}

bool LiveWheels::add(const hal::CanFrame& frame, std::int64_t arrival_ns) {
  bool used = true;
  {
    std::lock_guard lock(mutex_);
    if (!prior_) return true;
    hal::CanFrame stamped = frame;
    if (recorded_ == nullptr || recorded_stamp(frame, stamped.stamp_ns)) {
      (void)prior_->update(stamped);
      newest_arrival_ns_ = arrival_ns;
    } else {
      used = false;
    }
  }
  advanced_.notify_all();
  return used;
}

bool LiveWheels::motion_since(std::int64_t stamp_ns, Eigen::Isometry3d& T_then_now) {
  std::lock_guard lock(mutex_);
  if (!prior_) return false;
  RelativeMotion motion;
  if (prior_->odometry().relative_motion(stamp_ns, prior_->odometry().newest_stamp_ns(), motion) !=
      RelativeMotionStatus::kOk) {
    return false;
  }
  T_then_now = to_isometry3d(motion.T_a_b);
  return true;
}

bool LiveWheels::recorded_stamp(const hal::CanFrame& frame, std::int64_t& stamp_ns) {
  const std::vector<hal::CanFrame>& recorded = *recorded_;
  for (std::size_t i = next_recorded_; i < recorded.size() && i < next_recorded_ + kRecordedLookAhead; ++i) {
    const hal::CanFrame& candidate = recorded[i];
    if (candidate.id == frame.id && candidate.length == frame.length && candidate.data == frame.data) {
      stamp_ns = candidate.stamp_ns;
      next_recorded_ = i + 1;
      return true;
    }
  }
  return false;
}

}  // namespace rankslam::nav
