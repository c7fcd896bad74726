#include "rankslam/slam/slam_loop.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/stopwatch.hpp"

#include <cmath>
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

SlamLoop::SlamLoop(const SlamConfig& config, const hal::Calibration& calibration, const wide::Vocabulary* vocabulary)
    : config_(config),
      camera_(calibration),
      images_(camera_.width(), camera_.height(), config_.ir_switch_brightness),
      map_(config_, camera_),
      registrar_(config_, camera_, robust_estimator(config_), calibration.rgb.T_base_cam,
                 calibration.wheels.has_value(), companion_, geometric_),
      arbiter_(config.wheels, calibration.rgb.T_base_cam),
      keyframe_store_(make_keyframe_store(config_)),
      backend_(config_, calibration.rgb.T_base_cam, calibration.wheels.has_value()),
      local_(config_, camera_, keyframe_layout(config_).photometric_features),
      loop_closer_(config_, keyframe_store_, registrar_, geometric_, backend_),
      relocaliser_(config_, keyframe_store_, registrar_, geometric_),
      map_digests_{calibration_digest(calibration), config_digest(config_)} {
  images_.warm_up();
  if (const std::string error = team_.start(config_.threads); !error.empty()) {
    throw std::invalid_argument("slam.threads: " + error);
  }
  registrar_.share_with(&team_);
  if (calibration.fisheye && config_.wide.enabled()) {
    wide_ = std::make_unique<WideCloser>(config_, calibration, keyframe_store_, loop_closer_, backend_, vocabulary);
  }
  tracker_ = make_tracker({config_, camera_, images_, registrar_, geometric_, arbiter_, team_, companion_, backend_});
  if (keyframe_layout(config_).geometric_features > 0 && config_.loop.candidates_per_frame > 0 &&
      config_.loop.candidates_per_frame < config_.loop.max_candidates) {
    loop_closer_.keep_features_in(geometric_.make_features());  // a search may carry over into later frames
  }
}

FrameResult SlamLoop::process(const hal::RgbdFrame& frame) { return process(frame, nullptr); }

FrameResult SlamLoop::process(const hal::RgbdFrame& frame, const nav::MotionPrior* prior) {
  return process(frame, prior, nullptr);
}

FrameResult SlamLoop::process(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, const cv::Mat* wide) {
  FrameResult result;
  result.wheels.prior_given = prior != nullptr;
  tracker_->track(frame, prior, result);
  relocalise(result);
  finish_frame(frame, prior, wide, result);
  tracker_->end_frame(result);
  return result;
}

void SlamLoop::search_loaded_map() {
  in_map_ = false;
  lost_by_doubt_ = false;
  start_search();
}

void SlamLoop::start_search() {
  searching_ = true;
  searched_frames_ = 0;
  tracked_while_searching_ = 0;
  search_start_sequence_ = keyframe_sequence_;
  relocaliser_.reset();
}

void SlamLoop::relocalise(FrameResult& result) {
  failed_in_a_row_ = result.status == FrameStatus::kFailed ? failed_in_a_row_ + 1 : 0;
  const int after = config_.relocalisation.after_failed_frames;
  const bool searchable = after > 0 && keyframe_layout(config_).photometric_features > 0 && keyframe_store_.size() > 0;
  // The image's overlap with the tracking reference: a kidnapped robot in a place whose geometry
  // looks alike (a plain corridor) still registers, but most features find no match in one frame.
  // Matches, not inliers: the matcher searches around the predicted pose, so the few chance
  // matches of another place fit the prediction, and the inliers of a plain wall's features come
  // and go while their matches stay. A drop from an image that held the pose puts the frame's
  // pose in doubt: lost unless the search finds it, or finds tracking right. With wheels a drop
  // is left to the wheel/vision arbitration: in a plain corridor it also comes with turns and
  // slips, where a search took stretches that look alike.
  const bool doubted = searchable && in_map_ && result.status == FrameStatus::kTracking &&
                       !result.wheels.prior_given && last_photometric_matches_ >= config_.min_inliers &&
                       result.photometric_matches < config_.reference_min_overlap * last_photometric_matches_;
  last_photometric_matches_ = result.status == FrameStatus::kTracking ? result.photometric_matches : 0;
  // A doubted frame neither found nor confirmed by the map around tracking's pose is lost. Where
  // its image could have confirmed it (photometric matches enough), so is the chain from it: lost
  // until the search finds the camera in the map, as a loaded map is. A view whose features left
  // it (a plain wall filling it) gives the search nothing to place: the pose stays geometry's.
  const auto lose_unless_confirmed = [&] {
    if (!doubted || tracking_registers(result, 0, config_.min_inliers)) return;
    result.status = FrameStatus::kLost;
    if (result.photometric_matches >= config_.min_inliers) {
      in_map_ = false;
      lost_by_doubt_ = true;
    }
  };
  if (!searching_) {
    // The search needs descriptors to rank key-frames with, and key-frames.
    const bool failed = after > 0 && failed_in_a_row_ >= after;
    if (!searchable || !(failed || doubted)) return;
    start_search();
  }
  if (in_map_ && result.resumed) {
    searching_ = false;  // back on the reference from before the failure, which is in the map
    return;
  }
  // Outside the map's frame the pose tracking gives is not the map's.
  if (!in_map_) result.status = FrameStatus::kLost;
  ++searched_frames_;
  // A pose from registration, or from the wheels where it failed.
  const bool posed = result.status == FrameStatus::kTracking || result.status == FrameStatus::kWheels;
  // Frames posed since the last failure of the search: from a pose the map did not give.
  const int tracked_before = tracked_while_searching_;
  tracked_while_searching_ = posed ? tracked_while_searching_ + (doubted ? 0 : 1) : 0;
  Relocalisation found;
  if (!relocaliser_.search(tracker_->features(), loop_closer_.threshold(), result, found)) {
    // Tracking that went on after the failure without being found again within one sweep of the
    // store (and the confirmation) is on new ground: the search ends.
    const int sweep = (keyframe_store_.size() + config_.relocalisation.keyframes_per_frame - 1) /
                      config_.relocalisation.keyframes_per_frame;
    if (in_map_ && posed && searched_frames_ >= sweep + config_.relocalisation.confirm_frames) {
      searching_ = false;
    }
    lose_unless_confirmed();
    return;
  }
  // The chain in doubt since a drop went on from a pose: a place must be seen in the image to be
  // taken instead, as where tracking disagrees (below). The search goes on.
  if (lost_by_doubt_ && found.photometric_inliers < config_.min_inliers) return;
  searching_ = false;
  if (in_map_ && posed) {
    // Tracking went on after the failure: where the place found agrees with it within the drift
    // a loop closure may correct, tracking was right (the loop closure is the back-end's).
    const double travelled_m = path_since(found.slot, result.T_world_cam);
    const Eigen::Isometry3d difference = result.T_world_cam.inverse() * found.T_world_cam;
    if (config_.loop.within_drift(difference.translation().norm(), lie::rotation_deg(difference), travelled_m)) return;
    // A place that disagrees must be seen in the image (geometry alone cannot tell two stretches
    // of a plain corridor apart) and explain the frame better than the map around the pose
    // tracking gives does.
    if (found.photometric_inliers < config_.min_inliers) {
      lose_unless_confirmed();
      return;
    }
    if (tracking_registers(result, found.inliers, 0)) return;
    // Otherwise tracking went on elsewhere than the map is (a kidnapped robot): its poses since
    // the failure are withdrawn and the key-frames it made retired. Failed frames keep their
    // extrapolated poses, reported as failed.
    result.retracted_frames = tracked_before;
    for (int slot = 0; slot < keyframe_store_.capacity(); ++slot) {
      StoredKeyframe& keyframe = keyframe_store_.slot(slot);
      if (!keyframe.used || keyframe.sequence <= search_start_sequence_) continue;
      if (keyframe.node >= 0) backend_.remove_node(keyframe.node);
      map_.remove_keyframe(keyframe);
      keyframe_store_.release(slot);
      ++retired_keyframes_;
    }
  }
  const Eigen::Isometry3d T_world_held = result.T_world_cam;
  tracker_->relocalise(found.T_world_cam,
                       lie::symmetric_inverse(backend_.registration_information(
                           found.photometric_inliers + found.geometric_inliers, found.noise_scale)),
                       result);
  result.relocalised = true;
  // The map frame moved under the pose tracking held, as under a graph solve.
  result.map_correction = lie::renormalised(found.T_world_cam * T_world_held.inverse());
  result.graph_applied = true;
  // The next key-frame's sequential edge starts at the key-frame the frame was found with.
  latest_keyframe_slot_ = found.slot;
  T_world_last_keyframe_ = keyframe_store_.slot(found.slot).T_world_cam;
  // The path goes on from the key-frame found: drift allowances count from there.
  path_m_ = keyframe_store_.slot(found.slot).path_m;
  loop_closer_.set_relocalisation(keyframe_sequence_ + 1, path_m_);
  // The wheels measured nothing between the key-frame found (another time, or another run) and
  // this frame: an edge from them would pull the next key-frame towards it.
  backend_.forget_wheel_motion();
  in_map_ = true;
  lost_by_doubt_ = false;
  failed_in_a_row_ = 0;
  ++relocalisations_;
}

double SlamLoop::path_since(int slot, const Eigen::Isometry3d& T_world_cam) const {
  return path_m_ + (T_world_last_keyframe_.inverse() * T_world_cam).translation().norm() - keyframe_store_.slot(slot).path_m;
}

bool SlamLoop::tracking_registers(const FrameResult& result, int min_inliers, int min_photometric_inliers) {
  // The key-frames made before the search that a loop closure would consider from tracking's
  // pose, nearest first, as many as a searching frame registers.
  const TrackedFeatures features = tracker_->features();
  const double threshold = loop_closer_.threshold();
  double last_m = -1.0;
  int last_slot = -1;
  for (int tried = 0; tried < config_.relocalisation.keyframes_per_frame; ++tried) {
    int nearest = -1;
    double nearest_m = 0.0;
    for (int slot = 0; slot < keyframe_store_.capacity(); ++slot) {
      const StoredKeyframe& keyframe = keyframe_store_.slot(slot);
      if (!keyframe.used || keyframe.sequence > search_start_sequence_) continue;
      const Eigen::Isometry3d relative = keyframe.T_world_cam.inverse() * result.T_world_cam;
      const double distance_m = relative.translation().norm();
      if (distance_m > config_.loop.search_radius_m || lie::rotation_deg(relative) > config_.loop.search_rotation_deg) {
        continue;
      }
      // Strictly after the last one tried in (distance, slot) order.
      if (distance_m < last_m || (distance_m == last_m && slot <= last_slot)) continue;
      if (nearest < 0 || distance_m < nearest_m) {
        nearest = slot;
        nearest_m = distance_m;
      }
    }
    if (nearest < 0) return false;
    last_m = nearest_m;
    last_slot = nearest;
    FrameResult scratch;
    Relocalisation held;
    if (!relocaliser_.register_with(nearest, features, threshold, scratch, held)) continue;
    const Eigen::Isometry3d difference = result.T_world_cam.inverse() * held.T_world_cam;
    // Both are tracking's since that key-frame: they may differ by the drift over the path since.
    const double travelled_m = std::abs(path_since(nearest, result.T_world_cam));
    if (held.inliers >= min_inliers && held.photometric_inliers >= min_photometric_inliers &&
        config_.loop.within_drift(difference.translation().norm(), lie::rotation_deg(difference), travelled_m)) {
      return true;
    }
  }
  return false;
}

void SlamLoop::finish_frame(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, const cv::Mat* wide,
                            FrameResult& result) {
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
  if (wide_) {
    const bool tracked = result.status == FrameStatus::kTracking || result.status == FrameStatus::kFirstFrame;
    (void)wide_->update(frame.rgb, frame.depth, wide, tracked && in_map_, result.T_world_cam);
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
    // Every key-frame is protected: this frame is not stored, and the map holds only what the
    // store does.
    if (slot < 0) return;
    backend_.remove_node(keyframe_store_.slot(slot).node);
    map_.remove_keyframe(keyframe_store_.slot(slot));
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
  (void)local_.submit(keyframe_store_, backend_.graph());
  tracker_->keyframe_stored();
  keyframe.path_m = path_m_;
  if (have_depth) map_.add_keyframe(frame, images_, result.T_world_cam, &keyframe);
  latest_keyframe_slot_ = slot;
  if (wide_) wide_->keyframe_stored(slot);
  // A search still under way for the previous key-frame ends before this one's starts.
  loop_closer_.advance(0, result);
  if (result.status == FrameStatus::kTracking && keyframe.node >= 0) loop_closer_.start(slot, features.geometric);
}

void SlamLoop::run_backend(FrameResult& result) {
  (void)local_.take(backend_);
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
  if (wide_) (void)wide_->finish();
  local_.finish(backend_);
  backend_.finish(keyframe_store_, [this](const Eigen::Isometry3d& correction) { correct_tracking(correction); });
  // The live map holds the stored key-frames' points at the poses they were added at: those are
  // the poses there are unless a closure or local mapping moved them.
  if (loop_closer_.closures() == 0 && local_.counters().refined_edges == 0 &&
      (!wide_ || wide_->counters().edges == 0)) {
    return;
  }
  map_.rebuild(keyframe_store_);
}

std::string SlamLoop::save_map(const std::filesystem::path& path) const {
  return save_map_file(path, keyframe_store_, backend_.graph(), loop_closer_.adaptive_threshold(), map_digests_);
}

std::unique_ptr<MapSnapshot> SlamLoop::make_map_snapshot() const {
  auto snapshot = std::make_unique<MapSnapshot>(MapSnapshot{make_keyframe_store(config_), graph::PoseGraph(),
                                                            loop_closer_.adaptive_threshold(), map_digests_});
  if (const std::string error = snapshot->graph.configure(backend_.graph().capacity()); !error.empty()) {
    throw std::invalid_argument("map snapshot: " + error);
  }
  return snapshot;
}

void SlamLoop::snapshot_map(MapSnapshot& snapshot) const {
  (void)snapshot.store.copy_from(keyframe_store_);
  (void)snapshot.graph.copy_from(backend_.graph());
  snapshot.threshold = loop_closer_.adaptive_threshold();
  snapshot.digests = map_digests_;
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
  // The loaded map is the frame the run is placed in: optimisations move only what this run adds.
  graph::PoseGraph& graph = backend_.graph_to_restore();
  for (int node = 0; node < graph.capacity().max_nodes; ++node) (void)graph.hold(node);
  map_.rebuild(keyframe_store_);
  // Poses are in the loaded map's frame from the first frame found in it.
  if (keyframe_store_.size() > 0) search_loaded_map();
  return info;
}

}  // namespace rankslam::slam
