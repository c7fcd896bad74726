#include "rankslam/slam/slam_loop.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/stopwatch.hpp"

#include <stdexcept>
#include <string>

namespace rankslam::slam {
namespace {

KeyframeStore make_keyframe_store(const SlamConfig& config) {
  const KeyframeLayout layout = keyframe_layout(config);
  return {config.keyframe_capacity, layout.photometric_features, layout.geometric_features, layout.cloud_points,
          config.map.points_per_keyframe};
}

}  // namespace

SlamLoop::SlamLoop(const SlamConfig& config, const hal::Calibration& calibration)
    : config_(config),
      camera_(calibration),
      images_(camera_.width(), camera_.height(), config_.ir_switch_brightness),
      map_(config_, camera_),
      registrar_(config_, camera_, robust_estimator(config_), calibration.rgb.T_base_cam,
                 calibration.wheels.has_value(), companion_, geometric_),
      arbiter_(config.wheels, calibration.rgb.T_base_cam),
      keyframe_store_(make_keyframe_store(config_)),
      backend_(config_, calibration.rgb.T_base_cam, calibration.wheels.has_value()),
      loop_closer_(config_, keyframe_store_, registrar_, geometric_, backend_),
      map_digests_{calibration_digest(calibration), config_digest(config_)} {
  images_.warm_up();
  if (const std::string error = team_.start(config_.threads); !error.empty()) {
    throw std::invalid_argument("slam.threads: " + error);
  }
  registrar_.share_with(&team_);
  tracker_ = make_tracker({config_, camera_, images_, registrar_, geometric_, arbiter_, team_, companion_, backend_});
  if (keyframe_layout(config_).geometric_features > 0 && config_.loop.candidates_per_frame > 0 &&
      config_.loop.candidates_per_frame < config_.loop.max_candidates) {
    loop_closer_.keep_features_in(geometric_.make_features());  // a search may carry over into later frames
  }
}

FrameResult SlamLoop::process(const hal::RgbdFrame& frame) { return process(frame, nullptr); }

FrameResult SlamLoop::process(const hal::RgbdFrame& frame, const nav::MotionPrior* prior) {
  FrameResult result;
  result.wheels.prior_given = prior != nullptr;
  tracker_->track(frame, prior, result);
  finish_frame(frame, prior, result);
  tracker_->end_frame(result);
  return result;
}

void SlamLoop::finish_frame(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, FrameResult& result) {
  // The first frame starts the wheel motion the first key-frame's edges will span.
  backend_.accumulate_wheel_motion(result.status == FrameStatus::kFirstFrame ? nullptr : prior);
  if (!result.wheels.compared) {
    // The window and the runs count consecutive compared frames only.
    arbiter_.interrupt();
  }
  const auto stage_start = SteadyClock::now();
  const Eigen::Isometry3d since_keyframe = T_world_last_keyframe_.inverse() * result.T_world_cam;
  if (result.status == FrameStatus::kFirstFrame ||
      (result.status == FrameStatus::kTracking &&
       (since_keyframe.translation().norm() > config_.keyframe_translation_m ||
        lie::rotation_deg(since_keyframe) > config_.keyframe_rotation_deg))) {
    T_world_last_keyframe_ = result.T_world_cam;
    result.keyframe = true;
    ++keyframes_;
    store_keyframe(frame, images_.has_depth(frame), result);
  }
  loop_closer_.advance(config_.loop.candidates_per_frame, result);
  if (latest_keyframe_slot_ >= 0) {
    const StoredKeyframe& keyframe = keyframe_store_.slot(latest_keyframe_slot_);
    result.keyframe_node = keyframe.node;
    result.keyframe_generation = keyframe.generation;
    result.T_keyframe_cam = keyframe.T_world_cam.inverse() * result.T_world_cam;
  }
  run_backend(result);
  result.times.ms[StageTimes::kMapping] = elapsed_ms(stage_start);
}

void SlamLoop::store_keyframe(const hal::RgbdFrame& frame, bool have_depth, FrameResult& result) {
  int slot = keyframe_store_.free_slot();
  if (slot < 0) {
    // Full: retire a key-frame away from here (the loop search would not pick it soon) with the
    // fewest loop closures; its graph edges are composed through a neighbour, so the graph
    // stays connected.
    slot = keyframe_store_.retirement_candidate(result.T_world_cam, 2.0 * config_.loop.search_radius_m,
                                                config_.loop.min_keyframe_gap);
    if (slot < 0) {
      if (have_depth) map_.add_keyframe(frame, images_, result.T_world_cam, nullptr);
      return;
    }
    backend_.remove_node(keyframe_store_.slot(slot).node);
    keyframe_store_.release(slot);
    ++retired_keyframes_;
  }
  const TrackedFeatures features = tracker_->features();
  keyframe_store_.occupy(slot);
  StoredKeyframe& keyframe = keyframe_store_.slot(slot);
  keyframe.sequence = ++keyframe_sequence_;
  keyframe.stamp_s = frame.stamp_s;
  keyframe.T_world_cam = result.T_world_cam;
  keyframe.velocity = features.velocity;
  if (features.photometric != nullptr) {
    KeyframeStore::copy_features(*features.photometric, keyframe.photometric);
  } else {
    keyframe.photometric.clear();
  }
  if (features.geometric != nullptr && keyframe.geometric.capacity() > 0) {
    KeyframeStore::copy_features(*features.geometric, keyframe.geometric);
  } else {
    keyframe.geometric.count = 0;
  }
  keyframe.node = backend_.add_node(keyframe.T_world_cam, keyframe.generation);
  if (latest_keyframe_slot_ >= 0 && latest_keyframe_slot_ != slot) {
    const StoredKeyframe& previous = keyframe_store_.slot(latest_keyframe_slot_);
    const Eigen::Isometry3d T_previous_current = previous.T_world_cam.inverse() * keyframe.T_world_cam;
    path_m_ += T_previous_current.translation().norm();
    if (previous.used && previous.node >= 0 && keyframe.node >= 0) {
      backend_.add_sequential_edges(previous.node, keyframe.node, T_previous_current,
                                    tracker_->keyframe_edge_information(result));
    }
  }
  backend_.restart_wheel_motion();
  tracker_->keyframe_stored();
  keyframe.path_m = path_m_;
  if (have_depth) map_.add_keyframe(frame, images_, result.T_world_cam, &keyframe);
  latest_keyframe_slot_ = slot;
  // A search still under way for the previous key-frame ends before this one's starts.
  loop_closer_.advance(0, result);
  if (result.status == FrameStatus::kTracking && keyframe.node >= 0) loop_closer_.start(slot, features.geometric);
}

void SlamLoop::run_backend(FrameResult& result) {
  backend_.submit_pending();
  Eigen::Isometry3d correction;
  if (!backend_.take_solve(keyframe_store_, correction)) return;
  correct_tracking(correction);
  result.T_world_cam = lie::renormalised(correction * result.T_world_cam);
  result.graph_applied = true;
  result.map_correction = lie::renormalised(correction * result.map_correction);
}

void SlamLoop::correct_tracking(const Eigen::Isometry3d& correction) {
  tracker_->correct(correction);
  T_world_last_keyframe_ = lie::renormalised(correction * T_world_last_keyframe_);
}

void SlamLoop::finish() {
  {
    FrameResult ignored;
    loop_closer_.advance(0, ignored);
  }
  backend_.finish(keyframe_store_, [this](const Eigen::Isometry3d& correction) { correct_tracking(correction); });
  if (loop_closer_.closures() == 0) return;  // the live map already sits on the only poses there are
  map_.rebuild(keyframe_store_);
}

std::string SlamLoop::save_map(const std::filesystem::path& path) const {
  return save_map_file(path, keyframe_store_, backend_.graph(), loop_closer_.adaptive_threshold(), map_digests_);
}

MapFileInfo SlamLoop::load_map(const std::filesystem::path& path) {
  const MapFileInfo info = load_map_file(
      path, map_digests_, {keyframe_store_, backend_.graph_to_restore(), loop_closer_.adaptive_threshold()});
  keyframe_sequence_ = 0;
  path_m_ = 0.0;
  for (int i = 0; i < keyframe_store_.capacity(); ++i) {
    const StoredKeyframe& keyframe = keyframe_store_.slot(i);
    if (!keyframe.used || keyframe.sequence < keyframe_sequence_) continue;
    keyframe_sequence_ = keyframe.sequence;
    path_m_ = keyframe.path_m;
  }
  map_.rebuild(keyframe_store_);
  return info;
}

}  // namespace rankslam::slam
