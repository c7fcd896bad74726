#pragma once

#include "rankslam/sim/scene.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace rankslam::sim::detail {

/// A stretch in which one wheel's encoder over-counts (the wheel spins on the floor).
struct SlipSegment {
  std::int64_t start_ns = 0;
  std::int64_t end_ns = 0;
  int wheel = 0;            ///< 0 left, 1 right
  double over_count = 0.0;  ///< Extra ticks as a fraction of the true ticks.
};

struct WheelLogOptions {
  std::uint64_t seed = 1;
  std::int64_t epoch_ns = 0;  ///< Stamp of motion time 0.
  double begin_s = 0.0;       ///< Frames are written for motion times begin_s … end_s (inclusive),
  double end_s = 0.0;         ///< on the rate's grid counted from time 0.
  double rate_hz = 100.0;
  bool tick_noise = true;
  bool slip = true;
};

/// candump -l lines of the robot's WheelTicks frames (nav::encode_wheel_ticks) for a drive
/// motion, and the slip segments. Counters start near the 24-bit wrap so it happens early.
void build_wheel_log(const DriveMotion& motion, const hal::WheelGeometry& wheels, const WheelLogOptions& options,
                     std::string& can_log, std::vector<SlipSegment>& slips);

}  // namespace rankslam::sim::detail
