#include "rankslam/nav/pose_output.hpp"

#include "rankslam/nav/wheel_frame.hpp"

#include <algorithm>
#include <thread>

namespace rankslam::nav {

void PoseMailbox::post(const PoseSample& sample, const Eigen::Isometry3d* map_correction,
                       std::optional<std::int64_t> wheel_stamp_ns) {
  std::lock_guard lock(mutex_);
  if (map_correction != nullptr) pending_correction_ = *map_correction * pending_correction_;
  sample_ = sample;
  wheel_stamp_ns_ = wheel_stamp_ns;
  ++sample_count_;
  camera_fault_ = false;
}

void PoseMailbox::set_camera_fault(bool fault) {
  std::lock_guard lock(mutex_);
  camera_fault_ = fault;
}

void PoseMailbox::set_end_of_stream() {
  std::lock_guard lock(mutex_);
  end_of_stream_ = true;
}

void PoseMailbox::set_wide_camera_fault(bool fault) {
  std::lock_guard lock(mutex_);
  wide_camera_fault_ = fault;
}

void PoseMailbox::deliver(PoseBroadcaster& broadcaster, std::optional<std::int64_t>& wheel_stamp_ns) {
  std::lock_guard lock(mutex_);
  if (sample_count_ != delivered_count_ && sample_) {
    delivered_count_ = sample_count_;
    PoseSample sample = *sample_;
    sample.map_correction = pending_correction_;
    pending_correction_.setIdentity();
    wheel_stamp_ns = wheel_stamp_ns_;
    broadcaster.update(sample);
  }
  broadcaster.set_camera_state(camera_fault_, end_of_stream_, wide_camera_fault_);
}

PoseOutput::PoseOutput(const PoseOutputOptions& options, hal::CanBus& bus, const hal::Clock& clock,
                       PoseMailbox& mailbox, LiveWheels& wheels)
    : options_(options),
      bus_(bus),
      clock_(clock),
      mailbox_(mailbox),
      wheels_(wheels),
      broadcaster_(options.broadcast, bus, clock, options.wheel_noise) {}

void PoseOutput::run(const std::atomic<bool>& stop) {
  wheels_.mark_receiving();
  while (!stop.load()) step();
}

void PoseOutput::step() {
  // Wheel frames already queued first (a base's burst after a stall), so a due cycle carries
  // the newest odometry, not the one of the frame before; bounded to keep the cycle on time.
  hal::CanFrame frame;
  for (int i = 0; i < options_.max_queued_frames_per_step && bus_.receive(frame, std::chrono::milliseconds{0}) == hal::ReadStatus::kOk; ++i) {
    take_in(frame);
  }
  mailbox_.deliver(broadcaster_, sample_wheel_stamp_ns_);
  if (sample_wheel_stamp_ns_) {
    // The pose cycles move the latest SLAM pose on by the wheels since its camera frame.
    Eigen::Isometry3d T_then_now;
    if (wheels_.motion_since(*sample_wheel_stamp_ns_, T_then_now)) broadcaster_.set_wheel_motion(T_then_now);
  }
  const std::int64_t wait_ns = broadcaster_.poll();
  // Wait for the next due frame inside receive(), which also collects wheel frames.
  const auto wait = std::min(std::chrono::milliseconds(wait_ns / 1'000'000), options_.max_wait);
  const hal::ReadStatus status = bus_.receive(frame, wait);
  if (status == hal::ReadStatus::kOk) {
    take_in(frame);
  } else if (status == hal::ReadStatus::kFault) {
    std::this_thread::sleep_for(wait);  // the bus reopens on its own; do not spin meanwhile
  }
}

void PoseOutput::take_in(const hal::CanFrame& frame) {
  if (frame.id != options_.wheel_can_id || frame.extended) return;
  const auto ticks = decode_wheel_ticks(frame);
  if (!ticks) {
    ++wheel_counters_.malformed;
    return;
  }
  ++wheel_counters_.frames;
  if (last_counter_ && static_cast<std::uint8_t>(*last_counter_ + 1U) != ticks->rolling_counter) {
    ++wheel_counters_.counter_gaps;
  }
  last_counter_ = ticks->rolling_counter;
  if (!wheels_.add(frame, clock_.now_ns())) ++wheel_counters_.unmatched;
}

}  // namespace rankslam::nav
