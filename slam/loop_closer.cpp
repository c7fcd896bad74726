#include "rankslam/slam/loop_closer.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/slam/registration_support.hpp"


#include <algorithm>
#include <array>
#include <cmath>
#include <span>

namespace rankslam::slam {

LoopCloser::LoopCloser(const SlamConfig& config, KeyframeStore& store, Registrar& registrar,
                       geometry::GeometricFrontend& geometric, Backend& backend)
    : config_(config),
      store_(store),
      registrar_(registrar),
      geometric_(geometric),
      backend_(backend),
      threshold_(config.loop.initial_threshold, config.loop.threshold_deviations, config.loop.adaptive_threshold != 0) {
  candidates_.reserve(static_cast<std::size_t>(config_.keyframe_capacity));
  if (store_.capacity() > 0) {
    stored_decoded_ = store_.slot(0).geometric.make_decoded();
    current_decoded_ = store_.slot(0).geometric.make_decoded();
  }
  // One key-frame adds at most loop_max_candidates closures; the log holds many key-frames' worth.
  log_.resize(static_cast<std::size_t>(std::max(kClosureLogMinCapacity, 4 * config_.loop.max_candidates)));
}

double LoopCloser::travelled_m(const StoredKeyframe& current, const StoredKeyframe& stored) const {
  const bool current_since = current.sequence >= relocalised_first_sequence_;
  const bool stored_since = stored.sequence >= relocalised_first_sequence_;
  if (current_since == stored_since) return std::abs(current.path_m - stored.path_m);
  const StoredKeyframe& newer = current_since ? current : stored;
  const StoredKeyframe& older = current_since ? stored : current;
  return std::abs(newer.path_m - relocalised_path_m_) + std::abs(older.path_m - relocalised_path_m_);
}

void LoopCloser::start(int slot, const geometry::GeometricFeatures* geometric) {
  candidates_.clear();
  tried_ = next_ = 0;
  search_slot_ = -1;
  search_geometric_ = nullptr;
  if (config_.loop.max_candidates == 0) return;
  const StoredKeyframe& current = store_.slot(slot);
  for (int i = 0; i < store_.capacity(); ++i) {
    const StoredKeyframe& stored = store_.slot(i);
    if (!stored.used || i == slot || stored.node < 0) continue;
    if (stored.sequence > current.sequence - config_.loop.min_keyframe_gap) continue;
    if (geometric == nullptr && stored.photometric.source != current.photometric.source) continue;
    const double travelled_m = this->travelled_m(current, stored);
    const Eigen::Isometry3d relative = stored.T_world_cam.inverse() * current.T_world_cam;
    const double distance_m = relative.translation().norm();
    if (distance_m > config_.loop.search_radius_m + config_.loop.drift_per_m * travelled_m ||
        lie::rotation_deg(relative) > config_.loop.search_rotation_deg + config_.loop.drift_deg_per_m * travelled_m) {
      continue;
    }
    candidates_.push_back({distance_m, i, stored.sequence});
  }
  if (candidates_.empty()) return;
  tried_ = std::min(candidates_.size(), static_cast<std::size_t>(config_.loop.max_candidates));
  const auto tried_end = candidates_.begin() + static_cast<std::ptrdiff_t>(tried_);
  std::partial_sort(candidates_.begin(), tried_end, candidates_.end());
  // The frame's own features serve a search that ends in this frame; one that carries over into
  // the next frames keeps a copy (the frame's buffer is reused).
  const int per_frame = config_.loop.candidates_per_frame;
  search_geometric_ = geometric;
  if (geometric != nullptr && per_frame > 0 && tried_ > static_cast<std::size_t>(per_frame)) {
    if (!search_copy_.assign_from(*geometric)) return;  // set-up sizes both alike: not reached
    search_geometric_ = &search_copy_;
  }
  search_slot_ = slot;
  search_sequence_ = current.sequence;
}

void LoopCloser::advance(int count, FrameResult& result) {
  if (search_slot_ < 0) return;
  // Either key-frame may have been retired from the store since the search started.
  const StoredKeyframe& current = store_.slot(search_slot_);
  const bool current_kept = current.used && current.sequence == search_sequence_ && current.node >= 0;
  for (int done = 0; current_kept && next_ < tried_ && (count == 0 || done < count);
       ++done) {
    const Candidate& candidate = candidates_[next_++];
    StoredKeyframe& stored = store_.slot(candidate.slot);
    if (!stored.used || stored.sequence != candidate.sequence || stored.node < 0) continue;
    try_candidate(stored, result);
    ++result.loop_candidates;
  }
  if (!current_kept || next_ >= tried_) search_slot_ = -1;
}

void LoopCloser::try_candidate(StoredKeyframe& stored, FrameResult& result) {
  StoredKeyframe& current = store_.slot(search_slot_);
  const Eigen::Isometry3d predicted = stored.T_world_cam.inverse() * current.T_world_cam;
  // Below ε (set by the closures accepted so far, often in textured places) a registration with
  // tracking's min_inliers may still close the loop, where a neighbour of the stored key-frame
  // registers the new one to the same pose: a plain corridor's surfaces give fewer inliers.
  const bool corroborable = config_.loop.neighbour_agreement_m > 0.0;
  StoredRegistration registration;
  if (!register_stored(stored, current, predicted, corroborable ? config_.min_inliers : threshold_.value(),
                       registration)) {
    return;
  }
  const bool below_threshold =
      registration.photometric_inliers + registration.geometric_inliers < threshold_.value();
  const MotionEstimate& estimate = registration.estimate;
  const int photometric_inliers = registration.photometric_inliers;
  const int geometric_inliers = registration.geometric_inliers;
  const Eigen::Isometry3d& T_stored_current = registration.T_stored_current;

  // Inlier geometry: the matches that fit must spread in two directions at least; matches on a
  // line or in one small patch fit a wrong motion as well as the right one.
  const std::span<const Eigen::Vector3f> source_points = registrar_.source_points();
  const std::span<const Eigen::Vector3f> target_points = registrar_.target_points();
  const std::span<const double> correspondence_sigma_m = registrar_.correspondence_sigma_m();
  const InlierSpread spread =
      inlier_spread(estimate.T_target_source, source_points, target_points, correspondence_sigma_m);
  if (spread.inliers < config_.min_inliers || spread.axes_m(1) < config_.loop.min_inlier_spread_m) return;

  graph::Edge edge;
  edge.from = stored.node;
  edge.to = current.node;
  edge.T_from_to = lie::renormalised(T_stored_current);
  if (registration.refined_by_icp) {
    // As a sequential ICP-refined edge: what the surfaces fix, plus the feature inliers where
    // they fit their noise. A closure the view leaves free in a direction (a robot that turned
    // back to face the same plain corridor) then does not pull the chain along it.
    edge.information = cloud_surface_information(*search_geometric_, config_.graph.icp_sigma_m);
    if (estimate.noise_scale <= config_.fused.max_noise_scale) {
      edge.information += correspondence_information(estimate.T_target_source, source_points, target_points,
                                                     correspondence_sigma_m) /
                          std::max(1.0, estimate.noise_scale * estimate.noise_scale);
    }
  } else {
    edge.information = backend_.registration_information(photometric_inliers + geometric_inliers, estimate.noise_scale);
  }
  edge.kind = graph::EdgeKind::kLoopClosure;
  // Last, as it registers again (the edge's information above reads the registrar's inliers).
  // A closure that passed ε is judged by witnesses that pass it too; one below ε by any witness
  // with tracking's minimum.
  const Witness said =
      neighbours_say(stored, current, edge.T_from_to, below_threshold ? config_.min_inliers : threshold_.value());
  if (said == Witness::kDisagrees) {
    ++refuted_;
    return;
  }
  if (below_threshold && said != Witness::kAgrees) return;
  if (!backend_.add_loop_closure(edge)) return;
  ++stored.loop_closures;
  ++current.loop_closures;
  LoopClosure& logged = log_[static_cast<std::size_t>(closures_) % log_.size()];
  logged.stored_stamp_s = stored.stamp_s;
  logged.current_stamp_s = current.stamp_s;
  logged.T_stored_current = edge.T_from_to;
  logged.photometric_inliers = photometric_inliers;
  logged.geometric_inliers = geometric_inliers;
  logged.threshold = threshold_.value();
  // ε stays the statistics of closures that passed it on their own: with the corroborated ones it
  // falls with each, until closures far below any seen pass it unchecked.
  if (!below_threshold) threshold_.add(photometric_inliers, geometric_inliers);
  ++closures_;
  result.loop_closure = true;
}

bool LoopCloser::register_stored(const StoredKeyframe& stored, const StoredKeyframe& current,
                                 const Eigen::Isometry3d& predicted, double min_inliers,
                                 StoredRegistration& out) {
  // A key-frame's sequence names it (sequences start at 1): the current one is decoded once.
  if (search_geometric_ != nullptr && current_decoded_sequence_ != current.sequence) {
    current_decoded_sequence_ = current.geometric.decode(current_decoded_) ? current.sequence : 0;
  }
  // Sized from the store at set-up: a decode cannot fail.
  const bool with_geometry = search_geometric_ != nullptr && current_decoded_sequence_ == current.sequence &&
                             stored.geometric.decode(stored_decoded_);
  FrameResult scratch;
  out.estimate = registrar_.register_frames(
      stored.photometric, stored.velocity, current.photometric, current.velocity, scratch, predicted, predicted,
      with_geometry ? &stored_decoded_ : nullptr, with_geometry ? &current_decoded_ : nullptr, /*refine=*/false);
  if (!out.estimate.ok || !out.estimate.T_target_source.matrix().allFinite()) return false;
  out.photometric_inliers = with_geometry ? scratch.photometric_inliers : scratch.inliers;
  out.geometric_inliers = with_geometry ? scratch.geometric_inliers : 0;
  if (out.photometric_inliers + out.geometric_inliers < min_inliers) return false;
  // Where tracking needs the geometric ICP for its precision (photometric inliers few or poorly
  // spread), a closure on descriptor matches alone is less precise than the chain it would
  // correct: it is refined as tracking is, on the key-frame's stored cloud, the feature estimate
  // holding what the view leaves free, and is not taken unrefined.
  out.T_stored_current = out.estimate.T_target_source;
  out.refined_by_icp = false;
  if (with_geometry) {
    const StoredRefinement refinement =
        refine_on_stored_cloud(registrar_, geometric_, config_, config_.loop.icp_above_rotation_sigma_deg, stored_decoded_,
                               *search_geometric_, out.T_stored_current);
    if (refinement == StoredRefinement::kFailed) return false;
    out.refined_by_icp = refinement == StoredRefinement::kRefined;
  }
  // Pose consistency: a true closure corrects the drift accumulated since `stored`, no more; a
  // registration further off (a plain corridor matched turned end for end) is its own failure.
  const Eigen::Isometry3d correction =
      (stored.T_world_cam.inverse() * current.T_world_cam).inverse() * out.T_stored_current;
  return config_.loop.within_drift(correction.translation().norm(), lie::rotation_deg(correction),
                                   travelled_m(current, stored));
}

bool LoopCloser::agree(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) const {
  const Eigen::Isometry3d difference = a.inverse() * b;
  return difference.translation().norm() <= config_.loop.neighbour_agreement_m &&
         lie::rotation_deg(difference) <= config_.loop.neighbour_agreement_deg;
}

LoopCloser::Witness LoopCloser::witness(const StoredKeyframe& neighbour, const StoredKeyframe& current,
                                        const Eigen::Isometry3d& T_neighbour_current, double min_inliers,
                                        bool closure_moves) {
  // A witness needs `min_inliers` and the same ICP refinement and pose consistency as a closure;
  // one with only tracking's minimum still refutes a closure that moves the new key-frame from
  // where the chain has it, when it places the key-frame where the chain does.
  // (Where the closure keeps the chain's pose, a weaker registration could say nothing: not made.)
  StoredRegistration registration;
  const double least_inliers =
      closure_moves ? std::min(min_inliers, static_cast<double>(config_.min_inliers)) : min_inliers;
  if (!register_stored(neighbour, current, T_neighbour_current, least_inliers, registration)) return Witness::kNone;
  const bool agrees = agree(T_neighbour_current, registration.T_stored_current);
  if (registration.photometric_inliers + registration.geometric_inliers >= min_inliers) {
    return agrees ? Witness::kAgrees : Witness::kDisagrees;
  }
  const Eigen::Isometry3d T_neighbour_chain = neighbour.T_world_cam.inverse() * current.T_world_cam;
  const bool keeps_chain = agree(T_neighbour_chain, registration.T_stored_current);
  return !agrees && closure_moves && keeps_chain ? Witness::kDisagrees : Witness::kNone;
}

LoopCloser::Witness LoopCloser::neighbours_say(const StoredKeyframe& stored, const StoredKeyframe& current,
                                               const Eigen::Isometry3d& T_stored_current, double min_inliers) {
  if (config_.loop.neighbour_agreement_m <= 0.0) return Witness::kNone;
  // The nearest key-frame before and after the stored one in sequence, among the candidates' own.
  std::array<int, 2> neighbours{-1, -1};
  for (int i = 0; i < store_.capacity(); ++i) {
    const StoredKeyframe& other = store_.slot(i);
    if (!other.used || other.node < 0 || other.sequence == stored.sequence) continue;
    if (other.sequence > current.sequence - config_.loop.min_keyframe_gap) continue;
    const std::size_t side = other.sequence < stored.sequence ? 0 : 1;
    const int best = neighbours[side];
    if (best < 0 || std::abs(other.sequence - stored.sequence) < std::abs(store_.slot(best).sequence - stored.sequence)) {
      neighbours[side] = i;
    }
  }
  const bool closure_moves = !agree(stored.T_world_cam.inverse() * current.T_world_cam, T_stored_current);
  bool witnessed = false;
  for (const int slot : neighbours) {
    if (slot < 0) continue;
    const StoredKeyframe& neighbour = store_.slot(slot);
    const Eigen::Isometry3d T_neighbour_current =
        lie::renormalised(neighbour.T_world_cam.inverse() * stored.T_world_cam * T_stored_current);
    const Witness said = witness(neighbour, current, T_neighbour_current, min_inliers, closure_moves);
    if (said == Witness::kAgrees) return Witness::kAgrees;
    witnessed = witnessed || said == Witness::kDisagrees;
  }
  return witnessed ? Witness::kDisagrees : Witness::kNone;
}

const LoopClosure* LoopCloser::closure(int index) const {
  const int capacity = static_cast<int>(log_.size());
  if (index < 0 || index >= closures_ || index < closures_ - capacity) return nullptr;
  return &log_[static_cast<std::size_t>(index % capacity)];
}

}  // namespace rankslam::slam
