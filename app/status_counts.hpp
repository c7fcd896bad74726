#pragma once

#include "rankslam/slam/slam_loop.hpp"

namespace rankslam::app {

/// Frames by the status a consumer of the pose sees: TRACKING (registered), DEGRADED (the wheels
/// carry the pose), LOST (neither: extrapolated or held).
struct StatusCounts {
  int tracking = 0;
  int degraded = 0;
  int lost = 0;
  int disagreements = 0;   ///< registrations that disagreed with the wheels
  int wheels_trusted = 0;  ///< of which the wheels overruled a weak registration
  void add(const slam::FrameResult& result) {
    switch (result.status) {
      case slam::FrameStatus::kFirstFrame:
      case slam::FrameStatus::kTracking: ++tracking; break;
      case slam::FrameStatus::kWheels: ++degraded; break;
      case slam::FrameStatus::kFailed: ++lost; break;
    }
    if (result.wheels.disagree) ++disagreements;
    if (result.wheels.wheels_trusted) ++wheels_trusted;
  }
};

}  // namespace rankslam::app
