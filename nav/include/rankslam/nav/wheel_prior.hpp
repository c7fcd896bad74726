#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/nav/wheel_arbiter.hpp"
#include "rankslam/nav/wheel_odometry.hpp"

#include <Eigen/Geometry>

#include <cstdint>

namespace rankslam::nav {

/// Why a frame went without a wheel prior.
struct WheelPriorCounters {
  std::uint64_t with_prior = 0;
  std::uint64_t first_frame = 0;     ///< no previous frame to measure from
  std::uint64_t not_covered = 0;     ///< the wheel history does not reach one of the two stamps
  std::uint64_t discontinuous = 0;   ///< the odometry re-based between the two stamps
  std::uint64_t wrong_order = 0;     ///< the frame is older than the previous one
};

/// Wheel odometry as the SLAM loop's prior: the odometry is fed the wheel frames, and for each
/// camera frame prior_for() gives the camera's motion since the previous frame, the base's
/// motion between the two stamps carried through the camera's mounting. Allocates only at
/// construction (the odometry's history).
class WheelPrior {
 public:
  WheelPrior(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels,
             const Eigen::Isometry3d& T_base_cam);

  /// One CAN frame as received; frames with other identifiers are ignored.
  WheelFrameResult update(const hal::CanFrame& frame) { return odometry_.update(frame); }

  /// The prior for the camera frame at `stamp_ns` (on the wheel frames' clock), or null when the
  /// wheels do not cover the interval since the previous call. Valid until the next call.
  [[nodiscard]] const MotionPrior* prior_for(std::int64_t stamp_ns);

  [[nodiscard]] const WheelOdometry& odometry() const { return odometry_; }
  [[nodiscard]] const WheelPriorCounters& counters() const { return counters_; }

 private:
  WheelOdometry odometry_;
  Eigen::Isometry3d T_base_cam_;
  MotionPrior prior_;
  bool have_previous_ = false;
  std::int64_t previous_stamp_ns_ = 0;
  WheelPriorCounters counters_;
};

/// The camera frame's stamp on the wheel frames' clock: recording stamps carry microseconds, and
/// a double near 1.7e9 s resolves 0.24 µs, so rounding to the microsecond recovers the exact
/// stamps the CAN frames of the same recording have.
[[nodiscard]] std::int64_t recording_stamp_ns(double stamp_s);

}  // namespace rankslam::nav
