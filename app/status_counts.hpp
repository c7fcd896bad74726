#pragma once

#include "json_writer.hpp"
#include "rankslam/nav/wheel_prior.hpp"

#include "rankslam/slam/slam_loop.hpp"

#include <string>

namespace rankslam::app {

/// Frames by the status a consumer of the pose sees: TRACKING (registered), DEGRADED (the wheels
/// carry the pose), LOST (neither: extrapolated or held).
struct StatusCounts {
  int tracking = 0;
  int degraded = 0;
  int lost = 0;
  int disagreements = 0;   ///< registrations that disagreed with the wheels
  int wheels_trusted = 0;  ///< of which the wheels overruled the registration
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

/// The report.json entries `replay` and `run` share: `status_counts`, and how the wheels fared
/// (`wheels` null when they were not used, for `wheels_off_reason`).
inline void write_status_and_wheels(JsonWriter& json, const StatusCounts& counts, const nav::WheelPrior* wheels,
                                    int slip_events, const std::string& wheels_off_reason) {
  json.begin_object("status_counts");
  json.integer("TRACKING", counts.tracking);
  json.integer("DEGRADED", counts.degraded);
  json.integer("LOST", counts.lost);
  json.end_object();
  json.boolean("wheels_used", wheels != nullptr);
  if (wheels == nullptr) {
    json.string("wheels_off_reason", wheels_off_reason);
    json.null("wheel_slip_events");
    return;
  }
  const nav::WheelPriorCounters& prior = wheels->counters();
  const nav::WheelOdometryStats& odometry = wheels->odometry().stats();
  json.integer("wheel_slip_events", slip_events);
  json.integer("wheel_prior_frames", static_cast<long long>(prior.with_prior));
  json.integer("wheel_prior_missing", static_cast<long long>(prior.not_covered + prior.discontinuous + prior.wrong_order));
  json.integer("wheel_frames_integrated", static_cast<long long>(odometry.frames_integrated));
  json.integer("wheel_frames_missing", static_cast<long long>(odometry.frames_missing));
  json.integer("wheel_vision_disagreements", counts.disagreements);
  json.integer("wheel_overruled_frames", counts.wheels_trusted);
}

}  // namespace rankslam::app
