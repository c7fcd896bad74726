#include "rankslam/slam/slam_loop.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>

namespace rankslam::slam {
namespace {

using Clock = std::chrono::steady_clock;

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

double rotation_deg(const Eigen::Isometry3d& motion) {
  return Eigen::AngleAxisd(motion.rotation()).angle() * 180.0 / M_PI;
}

}  // namespace

SlamLoop::SlamLoop(const SlamConfig& config, const hal::Calibration& calibration)
    : config_(config),
      camera_(calibration.rgb, calibration.depth_scale),
      orb_(config_, camera_),
      estimator_(config_, static_cast<std::size_t>(config.orb_features) * 2),
      map_(config.map_voxel_m, static_cast<std::size_t>(config.map_max_points)),
      map_sampler_(static_cast<std::mt19937::result_type>(config.seed)) {
  const auto capacity = static_cast<std::size_t>(config.orb_features) * 2;
  for (auto* features : {&previous_, &current_}) {
    features->keypoints.reserve(capacity);
    features->points_cam.reserve(capacity);
    features->sigma_m.reserve(capacity);
  }
  matches_.reserve(capacity);
  source_points_.reserve(capacity);
  correspondence_sigma_m_.reserve(capacity);
  target_points_.reserve(capacity);
  gray_.create(camera_.height(), camera_.width(), CV_8UC1);
}

FrameResult SlamLoop::process(const hal::RgbdFrame& frame) {
  FrameResult result;
  auto stage_start = Clock::now();
  cv::cvtColor(frame.rgb, gray_, cv::COLOR_BGR2GRAY);
  result.times.ms[0] = elapsed_ms(stage_start);

  stage_start = Clock::now();
  orb_.extract(gray_, frame.depth, current_);
  result.features = static_cast<int>(current_.size());
  result.times.ms[1] = elapsed_ms(stage_start);

  if (!has_previous_) {
    result.status = FrameStatus::kFirstFrame;
    result.T_world_cam = Eigen::Isometry3d::Identity();
  } else {
    stage_start = Clock::now();
    matcher_.match(previous_.descriptors, current_.descriptors, config_.max_hamming_distance, matches_);
    source_points_.clear();
    target_points_.clear();
    correspondence_sigma_m_.clear();
    for (const FeatureMatch& match : matches_) {
      source_points_.push_back(current_.points_cam[match.target]);
      target_points_.push_back(previous_.points_cam[match.source]);
      const double sigma_source = current_.sigma_m[match.target];
      const double sigma_target = previous_.sigma_m[match.source];
      correspondence_sigma_m_.push_back(std::sqrt(sigma_source * sigma_source + sigma_target * sigma_target));
    }
    result.matches = static_cast<int>(matches_.size());
    result.times.ms[2] = elapsed_ms(stage_start);

    stage_start = Clock::now();
    // Estimate T_previous_current: current-frame points mapped into the previous frame.
    MotionEstimate estimate = estimator_.estimate(source_points_, target_points_, correspondence_sigma_m_);
    result.inliers = estimate.inliers;
    if (estimate.ok && estimate.inliers < config_.min_inliers) {
      estimate.ok = false;
      estimate.failure_reason = "too few inliers";
    }
    if (estimate.ok && (estimate.T_target_source.translation().norm() > config_.max_step_translation_m ||
                        rotation_deg(estimate.T_target_source) > config_.max_step_rotation_deg)) {
      estimate.ok = false;
      estimate.failure_reason = "implausible frame-to-frame motion";
    }
    if (estimate.ok && !estimate.T_target_source.matrix().allFinite()) {
      estimate.ok = false;
      estimate.failure_reason = "non-finite estimate";
    }
    if (estimate.ok) {
      last_motion_ = estimate.T_target_source;
      result.status = FrameStatus::kTracking;
    } else {
      // Constant-velocity propagation keeps the pose bounded and continuous through the gap.
      result.status = FrameStatus::kFailed;
      result.failure_reason = estimate.failure_reason;
    }
    result.T_world_cam = T_world_previous_ * last_motion_;
    result.times.ms[3] = elapsed_ms(stage_start);
  }

  stage_start = Clock::now();
  const Eigen::Isometry3d since_keyframe = T_world_last_keyframe_.inverse() * result.T_world_cam;
  if (result.status == FrameStatus::kFirstFrame ||
      (result.status == FrameStatus::kTracking &&
       (since_keyframe.translation().norm() > config_.keyframe_translation_m ||
        rotation_deg(since_keyframe) > config_.keyframe_rotation_deg))) {
    add_keyframe_to_map(frame, result.T_world_cam);
    T_world_last_keyframe_ = result.T_world_cam;
    result.keyframe = true;
    ++keyframes_;
  }
  result.times.ms[4] = elapsed_ms(stage_start);

  T_world_previous_ = result.T_world_cam;
  std::swap(previous_, current_);
  has_previous_ = true;
  return result;
}

void SlamLoop::add_keyframe_to_map(const hal::RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam) {
  const Eigen::Isometry3f T = T_world_cam.cast<float>();
  std::uniform_int_distribution<int> column(0, camera_.width() - 1);
  std::uniform_int_distribution<int> row(0, camera_.height() - 1);
  const auto max_depth_m = static_cast<float>(config_.max_depth_m);
  // Random pixels, as the thesis samples its map; attempts are capped so a frame with little
  // depth cannot stall the loop.
  int added = 0;
  for (int attempt = 0; attempt < config_.map_points_per_keyframe * 4 && added < config_.map_points_per_keyframe;
       ++attempt) {
    const int u = column(map_sampler_);
    const int v = row(map_sampler_);
    const unsigned short raw = frame.depth.at<unsigned short>(v, u);
    if (raw == 0) continue;
    const float z_m = camera_.metres(raw);
    if (z_m > max_depth_m) continue;
    const cv::Vec3b bgr = frame.rgb.at<cv::Vec3b>(v, u);
    map_.insert(T * camera_.back_project(u, v, z_m), bgr[0], bgr[1], bgr[2]);
    ++added;
  }
}

}  // namespace rankslam::slam
