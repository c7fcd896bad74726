#include "frame_pipeline.hpp"

#include "exit_codes.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/stopwatch.hpp"
#include "rankslam/nav/pose_frames.hpp"

#include <exception>
#include <iostream>

namespace rankslam::app {

bool ReplayedWheels::prior_for(std::int64_t stamp_ns, nav::MotionPrior& prior) {
  // The bus releases the wheel frames up to the camera frame's stamp and the first one after
  // it: the motion up to the stamp is known once the next wheel frame is in (at 100 Hz, at most
  // 10 ms later; a live camera frame takes longer than that to arrive).
  bus_.release_through(stamp_ns);
  hal::CanFrame frame;
  while (bus_.receive(frame, std::chrono::milliseconds(0)) == hal::ReadStatus::kOk) (void)wheels_.update(frame);
  const nav::MotionPrior* found = wheels_.prior_for(stamp_ns);
  if (found == nullptr) return false;
  prior = *found;
  return true;
}

bool ReceivedWheels::prior_for(std::int64_t stamp_ns, nav::MotionPrior& prior) {
  const bool playing = player_ && !player_->finished();
  const auto keep_waiting = [&](std::int64_t newest_arrival_ns) {
    return playing ? !player_->finished() : hal::MonotonicClock{}.now_ns() - newest_arrival_ns < 200'000'000;
  };
  return wheels_.prior_for(stamp_ns, playing ? std::chrono::milliseconds(1000) : std::chrono::milliseconds(30),
                           keep_waiting, prior);
}

FramePipeline::FramePipeline(const slam::SlamConfig& config, const hal::Calibration& calibration, WheelSource* wheels,
                             const PipelineOptions& options)
    : options_(options), T_base_cam_(calibration.rgb.T_base_cam), loop_(config, calibration, options.vocabulary), wheels_(wheels) {
  loop_.set_synchronous_backend(options.synchronous_backend);
  trajectory_.reserve(options.max_frames);
  relocalisations_.reserve(kMaxRelocalisations);
  if (options.frame_log) {
    frame_records_.reserve(options.max_frames);
    frame_ms_.reserve(options.max_frames);
    for (auto& stage : stage_ms_) stage.reserve(options.max_frames);
    keyframe_links_.reserve(options.max_frames);
  }
}

std::int64_t FramePipeline::wheel_stamp_ns(const hal::RgbdFrame& frame) const {
  return options_.recording_clock ? nav::recording_stamp_ns(frame.stamp_s) : frame.stamp_ns;
}

slam::FrameResult FramePipeline::process(const hal::RgbdFrame& frame, const hal::ImageFrame* wide) {
  const nav::MotionPrior* prior = nullptr;
  if (wheels_ != nullptr && wheels_->prior_for(wheel_stamp_ns(frame), prior_)) prior = &prior_;
  const auto start = SteadyClock::now();
  slam::FrameResult result = loop_.process(frame, prior, wide != nullptr ? &wide->image : nullptr);
  const double frame_ms = elapsed_ms(start);
  status_counts_.add(result);
  if (result.graph_applied) T_world_odom_ = lie::renormalised(result.map_correction * T_world_odom_);
  const Eigen::Isometry3d T_odom_cam = T_world_odom_.inverse() * result.T_world_cam;
  T_odom_base_ = T_base_cam_ * T_odom_cam * T_base_cam_.inverse();
  sigmas_.reset();
  // The covariance is of the pose since the first frame, which the corrections do not change:
  // the odom pose's.
  if (result.odom_covariance_valid) {
    // As PoseQuality carries them: quantised, saturated.
    const nav::PoseSigmas sigmas = nav::pose_sigmas(T_odom_cam, result.odom_covariance, T_base_cam_);
    nav::PoseQuality quality;
    quality.position_sigma_m = sigmas.position_m;
    quality.yaw_sigma_deg = sigmas.yaw_deg;
    const auto sent = nav::decode_pose_quality(nav::encode_pose_quality(quality, 0));
    if (sent && sent->position_sigma_m && sent->yaw_sigma_deg) sigmas_ = nav::PoseSigmas{*sent->position_sigma_m, *sent->yaw_sigma_deg};
  }
  if (result.status == slam::FrameStatus::kFailed || result.status == slam::FrameStatus::kWheels ||
      result.status == slam::FrameStatus::kLost) {
    ++failed_frames_;
  }
  if (result.relocalised) {
    for (int i = 0; i < result.retracted_frames && !trajectory_.empty(); ++i) {
      trajectory_.pop_back();
      if (!keyframe_links_.empty()) keyframe_links_.pop_back();
    }
    if (relocalisations_.size() < kMaxRelocalisations) {
      relocalisations_.push_back({frames_, frame.stamp_s, result.T_world_cam, result.retracted_frames});
    }
  }
  ++frames_;
  // A lost frame's pose is unknown: it has none in the trajectory.
  const bool pose_known = result.status != slam::FrameStatus::kLost;
  const bool kept = trajectory_.size() < options_.max_frames;
  if (kept && pose_known) {
    trajectory_.push_back({frame.stamp_s, result.T_world_cam});
  } else if (!kept) {
    ++trajectory_overflow_;
  }
  if (options_.frame_log && kept) {
    frame_ms_.push_back(frame_ms);
    for (std::size_t i = 0; i < slam::StageTimes::kCount; ++i) stage_ms_[i].push_back(result.times.ms[i]);
    frame_records_.push_back(eval::frame_record(frame.stamp_s, result));
    frame_records_.back().T_odom_base = T_odom_base_;
    frame_records_.back().sigmas = sigmas_;
    if (pose_known) keyframe_links_.push_back({result.keyframe_node, result.keyframe_generation, result.T_keyframe_cam});
    for (auto i = static_cast<int>(closures_.size()); i < loop_.loop_closures(); ++i) {
      if (const slam::LoopClosure* closure = loop_.loop_closure(i); closure != nullptr) closures_.push_back(*closure);
    }
    collect_wide_edges();
  }
  return result;
}

int FramePipeline::load_map(const std::filesystem::path& path) {
  try {
    const slam::MapFileInfo info = loop_.load_map(path);
    std::cout << "map loaded from " << path.string() << " (" << info.keyframes << " key-frames, written by "
              << info.software_version << "); LOST until the camera is found in it" << std::endl;
    return kExitOk;
  } catch (const std::exception& error) {
    std::cerr << "error: " << error.what() << "\n";
    return kExitInput;
  }
}

void FramePipeline::collect_wide_edges() {
  const slam::WideCounters* wide = loop_.wide_counters();
  if (wide == nullptr) return;
  for (auto i = wide_edges_taken_; i < wide->edges; ++i) {
    if (const slam::LoopClosure* edge = loop_.wide_edge(i); edge != nullptr) wide_edges_.push_back(*edge);
  }
  wide_edges_taken_ = wide->edges;
}

void FramePipeline::finish() {
  loop_.finish();
  if (!options_.frame_log) return;
  collect_wide_edges();
  for (std::size_t i = 0; i < trajectory_.size(); ++i) {
    const KeyframeLink& link = keyframe_links_[i];
    Eigen::Isometry3d optimized;
    if (loop_.optimized_pose(link.node, link.generation, link.T_keyframe_cam, optimized)) trajectory_[i].T_world_cam = optimized;
  }
}

void write_local_map(eval::JsonWriter& json, const slam::SlamLoop& loop) {
  if (loop.local_map() == nullptr) {
    json.null("local_map");
    return;
  }
  const slam::LocalMapCounters& local = *loop.local_map();
  json.begin_object("local_map");
  json.integer("adjustments", local.adjustments);
  json.integer("failed_adjustments", local.failed);
  json.integer("refined_edges", local.refined_edges);
  json.integer("last_landmarks", local.landmarks);
  json.integer("last_observations", local.observations);
  json.integer("last_inlier_observations", local.inlier_observations);
  json.number("mean_adjust_ms", local.adjustments > 0 ? local.adjust_ms / local.adjustments : 0.0);
  json.end_object();
}

}  // namespace rankslam::app
