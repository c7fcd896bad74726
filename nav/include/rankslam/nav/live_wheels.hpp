#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/nav/wheel_prior.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <vector>

namespace rankslam::nav {

/// The wheel odometry of a run, shared by two threads: the pose output feeds it the wheel frames
/// it receives from the bus, the SLAM thread takes each camera frame's prior from it. Allocates
/// only in enable().
class LiveWheels {
 public:
  /// A received frame further than this many frames past the last match is never matched: the
  /// bus may drop a few, not reorder.
  static constexpr std::size_t kRecordedLookAhead = 16;

  /// Wheels as the motion prior. `recorded`: a recording's CAN frames played onto the bus, whose
  /// stamps the received frames take back (matched by identifier and data, in order), so the
  /// odometry runs on the recording's clock as the replay camera does; null for a live base.
  void enable(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels, const Eigen::Isometry3d& T_base_cam,
              const std::vector<hal::CanFrame>* recorded);
  [[nodiscard]] bool enabled() const { return prior_.has_value(); }

  /// The receiving thread's bus is open: frames sent from now on reach it.
  void mark_receiving();
  /// Waits up to `wait` for mark_receiving(); false on time-out.
  [[nodiscard]] bool wait_receiving(std::chrono::milliseconds wait);

  /// A wheel frame received at `arrival_ns` (monotonic). False when it matches no recorded frame
  /// (replay through the bus) and was left out; true when used or when wheels are not enabled.
  bool add(const hal::CanFrame& frame, std::int64_t arrival_ns);

  /// The base's motion from `stamp_ns` to the newest wheel frame (T_then_now); false when the
  /// odometry does not cover it.
  [[nodiscard]] bool motion_since(std::int64_t stamp_ns, Eigen::Isometry3d& T_then_now);

  /// The prior for the camera frame at `stamp_ns` into `prior`, once a wheel frame at or after
  /// the stamp is in: waits for it up to `wait` while `keep_waiting(newest_arrival_ns)` holds.
  /// False without a prior for the frame.
  template <typename KeepWaiting>
  [[nodiscard]] bool prior_for(std::int64_t stamp_ns, std::chrono::milliseconds wait, KeepWaiting keep_waiting,
                               MotionPrior& prior) {
    std::unique_lock lock(mutex_);
    if (!prior_) return false;
    (void)advanced_.wait_for(lock, wait, [&] {
      return prior_->odometry().newest_stamp_ns() >= stamp_ns || !keep_waiting(newest_arrival_ns_);
    });
    const MotionPrior* found = prior_->prior_for(stamp_ns);
    if (found == nullptr) return false;
    prior = *found;
    return true;
  }

  /// The odometry and its counters, for the report; only once the receiving thread has stopped.
  [[nodiscard]] const WheelPrior* prior() const { return prior_ ? &*prior_ : nullptr; }

 private:
  /// The recording stamp of a played frame: the next recorded frame equal to it, looked for a
  /// few frames ahead. False when none matches.
  bool recorded_stamp(const hal::CanFrame& frame, std::int64_t& stamp_ns);

  std::mutex mutex_;
  std::condition_variable advanced_;  ///< a wheel frame was integrated, or the receiver started
  std::optional<WheelPrior> prior_;
  std::int64_t newest_arrival_ns_ = 0;
  bool receiving_ = false;
  const std::vector<hal::CanFrame>* recorded_ = nullptr;
  std::size_t next_recorded_ = 0;
};

}  // namespace rankslam::nav
