#include "geometric_tracker.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/stopwatch.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rankslam::slam {
namespace {

using enum StageTimes::Stage;

}  // namespace

GeometricTracker::GeometricTracker(const TrackerParts& parts) : parts_(parts), motion_(parts.config) {
  if (const std::string error = parts_.geometric.configure(parts.camera, parts.config.geometric_frontend(),
                                                                  geometric_capacities(parts.config),
                                                                  &parts_.team);
      !error.empty()) {
    throw std::invalid_argument(error);
  }
  for (auto& features : features_) features = parts_.geometric.make_features();
}

void GeometricTracker::track(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, FrameResult& result) {
  auto stage_start = SteadyClock::now();
  const bool have_depth = parts_.images.has_depth(frame);
  parts_.images.skip_features(frame);  // the map's colour only
  result.times.ms[kPreprocess] = elapsed_ms(stage_start);

  stage_start = SteadyClock::now();
  current_ = previous_ == 0 ? 1 : 0;
  geometry::GeometricFeatures& features = features_[static_cast<std::size_t>(current_)];
  const geometry::GeometryStatus extracted =
      have_depth ? parts_.geometric.extract(frame.depth, features) : geometry::GeometryStatus::kInvalidImage;
  if (extracted != geometry::GeometryStatus::kOk) features.count = 0;
  result.features = features.count;
  result.times.ms[kFeatures] = elapsed_ms(stage_start);

  if (previous_ < 0) {
    result.status = FrameStatus::kFirstFrame;
    result.T_world_cam = Eigen::Isometry3d::Identity();
    return;
  }
  std::string_view reason;
  if (!have_depth) {
    reason = "no usable depth";
  } else if (extracted != geometry::GeometryStatus::kOk) {
    reason = geometry::to_string(extracted);
  }
  bool tracked = false;
  if (reason.empty()) {
    // The target is the last frame with features, which is older than the previous frame when
    // frames without features came in between.
    const Eigen::Isometry3d guess = T_world_target_.inverse() * T_world_previous_ * motion_.predicted(prior);
    const geometry::FrameRegistration registration =
        parts_.geometric.register_frames(features_[static_cast<std::size_t>(previous_)], features, guess);
    const geometry::StageTimes& times = parts_.geometric.last_times();
    result.times.ms[kMatching] = times.matching_ms;
    result.times.ms[kEstimation] = times.msse_ms;
    result.times.ms[kIcp] = times.icp_ms;
    result.matches = registration.matches;
    // With the ICP stage the final inliers are its point-to-plane inliers; without it, MSSE's.
    result.inliers = registration.refined_from != geometry::RefinementStart::kNone ? registration.icp_inliers
                                                                                   : registration.inliers;
    // How strongly the scene fixes the motion: the descriptor matches' MSSE inliers. ICP's
    // point inliers count in the thousands even where it slides along a plane.
    const int descriptor_inliers = registration.msse_ok ? registration.inliers : 0;
    MotionEstimate estimate;
    estimate.ok = registration.ok;
    estimate.T_target_source = registration.T_previous_current;
    estimate.inliers = result.inliers;
    estimate.failure_reason = geometry::to_string(registration.status);
    tracked = motion_.accept(estimate, T_world_target_, T_world_previous_, motion_.predicted(prior),
                             result.T_world_cam, reason);
    if (tracked && prior != nullptr &&
        !parts_.arbiter.arbitrate(*prior, T_world_previous_, descriptor_inliers, result.T_world_cam, result.wheels)) {
      tracked = false;
      reason = "registration disagrees with the wheels";
    }
  }
  result.status = tracked ? FrameStatus::kTracking : (prior != nullptr ? FrameStatus::kWheels : FrameStatus::kFailed);
  if (!tracked) result.failure_reason = reason;
  motion_.finish(T_world_previous_, prior, result);
}

TrackedFeatures GeometricTracker::features() const {
  return {nullptr, &features_[static_cast<std::size_t>(current_)], Registrar::Velocity::Zero()};
}

Eigen::Matrix<double, 6, 6> GeometricTracker::keyframe_edge_information(const FrameResult& result) const {
  return parts_.backend.registration_information(std::max(result.inliers, parts_.config.min_inliers),
                                                 result.noise_scale);
}

void GeometricTracker::correct(const Eigen::Isometry3d& correction) {
  T_world_previous_ = lie::renormalised(correction * T_world_previous_);
  T_world_target_ = lie::renormalised(correction * T_world_target_);
}

void GeometricTracker::relocalise(const Eigen::Isometry3d& T_world_cam, const Eigen::Matrix<double, 6, 6>& /*covariance*/,
                                  FrameResult& result) {
  result.T_world_cam = T_world_cam;
  result.status = FrameStatus::kTracking;
  result.failure_reason = {};
  motion_.relocalised(T_world_cam);
}

void GeometricTracker::end_frame(FrameResult& result) {
  // A frame without features cannot be the next frame's target; the last good one stays.
  if (features_[static_cast<std::size_t>(current_)].count > 0 || previous_ < 0) {
    previous_ = current_;
    T_world_target_ = result.T_world_cam;
  }
  T_world_previous_ = result.T_world_cam;
}

}  // namespace rankslam::slam
