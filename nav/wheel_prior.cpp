#include "rankslam/nav/wheel_prior.hpp"

#include <cmath>

namespace rankslam::nav {

WheelPrior::WheelPrior(const WheelOdometryConfig& config, const hal::WheelGeometry& wheels,
                       const Eigen::Isometry3d& T_base_cam)
    : odometry_(config, wheels), T_base_cam_(T_base_cam) {}

const MotionPrior* WheelPrior::prior_for(std::int64_t stamp_ns) {
  const bool had_previous = have_previous_;
  const std::int64_t previous_ns = previous_stamp_ns_;
  have_previous_ = true;
  previous_stamp_ns_ = stamp_ns;
  if (!had_previous) {
    ++counters_.first_frame;
    return nullptr;
  }
  RelativeMotion motion;
  switch (odometry_.relative_motion(previous_ns, stamp_ns, motion)) {
    case RelativeMotionStatus::kOk: break;
    case RelativeMotionStatus::kNotInHistory: ++counters_.not_covered; return nullptr;
    case RelativeMotionStatus::kDiscontinuous: ++counters_.discontinuous; return nullptr;
    case RelativeMotionStatus::kWrongOrder: ++counters_.wrong_order; return nullptr;
  }
  prior_ = camera_motion_prior(motion.T_a_b.x_m, motion.T_a_b.y_m, motion.T_a_b.yaw_rad, motion.covariance,
                                     T_base_cam_);
  ++counters_.with_prior;
  return &prior_;
}

std::int64_t recording_stamp_ns(double stamp_s) { return std::llround(stamp_s * 1e6) * 1000; }

}  // namespace rankslam::nav
