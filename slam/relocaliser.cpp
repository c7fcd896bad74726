#include "rankslam/slam/relocaliser.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/slam/registration_support.hpp"

#include <algorithm>

namespace rankslam::slam {

Relocaliser::Relocaliser(const SlamConfig& config, const KeyframeStore& store, Registrar& registrar,
                         geometry::GeometricFrontend& geometric)
    : config_(config), store_(store), registrar_(registrar), geometric_(geometric) {
  if (store_.capacity() > 0) decoded_ = store_.slot(0).geometric.make_decoded();
}

void Relocaliser::reset() {
  cursor_ = 0;
  agreeing_ = 0;
}

bool Relocaliser::search(const TrackedFeatures& frame, double threshold, FrameResult& result, Relocalisation& found) {
  if (frame.photometric == nullptr) {
    agreeing_ = 0;
    return false;
  }
  // The last frame's key-frame first while confirming, then the next key-frames of the round
  // robin; the registration with the most inliers is the frame's hypothesis.
  Relocalisation best;
  Relocalisation candidate;
  int budget = config_.relocalisation.keyframes_per_frame;
  if (agreeing_ > 0 && usable(last_slot_, *frame.photometric)) {
    --budget;
    ++result.relocalisation_candidates;
    if (try_keyframe(last_slot_, frame, threshold, candidate, result)) best = candidate;
  }
  const int capacity = store_.capacity();
  for (int visited = 0; visited < capacity && budget > 0; ++visited) {
    const int slot = cursor_;
    cursor_ = (cursor_ + 1) % capacity;
    if ((agreeing_ > 0 && slot == last_slot_) || !usable(slot, *frame.photometric)) continue;
    --budget;
    ++result.relocalisation_candidates;
    if (try_keyframe(slot, frame, threshold, candidate, result) &&
        (best.slot < 0 || candidate.inliers > best.inliers)) {
      best = candidate;
    }
  }
  if (best.slot < 0) {
    agreeing_ = 0;
    return false;
  }
  // Consecutive relocalisations agree when they differ by no more than the tracker lets one
  // frame's motion differ from the last.
  const Eigen::Isometry3d step = T_world_last_.inverse() * best.T_world_cam;
  const bool agrees = agreeing_ > 0 && step.translation().norm() <= config_.max_deviation_translation_m &&
                      lie::rotation_deg(step) <= config_.max_deviation_rotation_deg;
  agreeing_ = agrees ? agreeing_ + 1 : 1;
  T_world_last_ = best.T_world_cam;
  last_slot_ = best.slot;
  if (agreeing_ < config_.relocalisation.confirm_frames) return false;
  refine(frame, best, result);
  found = best;
  reset();
  return true;
}

void Relocaliser::refine(const TrackedFeatures& frame, Relocalisation& found, FrameResult& result) {
  const StoredKeyframe& stored = store_.slot(found.slot);
  if (frame.geometric == nullptr || stored.geometric.count == 0 || !stored.geometric.decode(decoded_)) return;
  // The registrar holds the last key-frame tried; the found one's registration is made again
  // (the same estimate) for the refinement to start from.
  FrameResult scratch;
  scratch.times = result.times;
  const MotionEstimate estimate = registrar_.register_frames(
      stored.photometric, stored.velocity, *frame.photometric, frame.velocity, scratch, Eigen::Isometry3d::Identity(),
      Eigen::Isometry3d::Identity(), &decoded_, frame.geometric, /*refine=*/false);
  result.times = scratch.times;
  if (!estimate.ok || !lie::is_finite_rigid(estimate.T_target_source)) return;
  Eigen::Isometry3d T_stored_current = estimate.T_target_source;
  // Where ICP cannot fix what the features leave loose, the features' estimate stands: tracking
  // from it is better than staying lost, and loop closures correct it.
  if (refine_on_stored_cloud(registrar_, geometric_, config_, config_.loop.icp_above_rotation_sigma_deg, decoded_,
                             *frame.geometric, T_stored_current) == StoredRefinement::kRefined) {
    found.T_world_cam = lie::renormalised(stored.T_world_cam * T_stored_current);
  }
}

bool Relocaliser::register_with(int slot, const TrackedFeatures& frame, double threshold, FrameResult& result,
                                Relocalisation& found) {
  return frame.photometric != nullptr && usable(slot, *frame.photometric) &&
         try_keyframe(slot, frame, threshold, found, result);
}

bool Relocaliser::usable(int slot, const PhotometricFeatures& features) const {
  const StoredKeyframe& stored = store_.slot(slot);
  return stored.used && stored.node >= 0 && stored.photometric.source == features.source;
}

bool Relocaliser::try_keyframe(int slot, const TrackedFeatures& frame, double threshold, Relocalisation& found,
                               FrameResult& result) {
  const StoredKeyframe& stored = store_.slot(slot);
  const bool with_geometry =
      frame.geometric != nullptr && stored.geometric.count > 0 && stored.geometric.decode(decoded_);
  FrameResult scratch;
  scratch.times = result.times;
  const MotionEstimate estimate = registrar_.register_frames(
      stored.photometric, stored.velocity, *frame.photometric, frame.velocity, scratch, Eigen::Isometry3d::Identity(),
      Eigen::Isometry3d::Identity(), with_geometry ? &decoded_ : nullptr,
      with_geometry ? frame.geometric : nullptr, /*refine=*/false);
  result.times = scratch.times;
  if (!estimate.ok || !lie::is_finite_rigid(estimate.T_target_source)) return false;
  // Inliers that fit far worse than their noise, as the tracker would not take for its reference.
  if (estimate.noise_scale > config_.reference_max_noise_scale) return false;
  // As a loop closure must: enough inliers for the adaptive threshold, spread in two directions.
  const int photometric_inliers = with_geometry ? scratch.photometric_inliers : scratch.inliers;
  const int geometric_inliers = with_geometry ? scratch.geometric_inliers : 0;
  if (photometric_inliers + geometric_inliers < threshold) return false;
  const InlierSpread spread = inlier_spread(estimate.T_target_source, registrar_.source_points(),
                                            registrar_.target_points(), registrar_.correspondence_sigma_m());
  if (spread.inliers < config_.min_inliers || spread.axes_m(1) < config_.loop.min_inlier_spread_m) return false;
  found.T_world_cam = lie::renormalised(stored.T_world_cam * estimate.T_target_source);
  found.slot = slot;
  found.inliers = photometric_inliers + geometric_inliers;
  found.photometric_inliers = photometric_inliers;
  found.geometric_inliers = geometric_inliers;
  found.noise_scale = estimate.noise_scale;
  return true;
}

}  // namespace rankslam::slam
