#include "rankslam/slam/wide_closer.hpp"

#include "rankslam/core/lie.hpp"

#include <algorithm>
#include <cmath>

namespace rankslam::slam {
namespace {

/// χ² of 6 degrees of freedom at 99 %.
constexpr double kChiSquare6Dof99 = 16.81;

wide::WideMapperOptions mapper_options(const SlamConfig& config, const wide::Vocabulary* vocabulary) {
  wide::WideMapperOptions options;
  options.vocabulary = vocabulary;
  options.capacity = config.keyframe_capacity;
  options.registration.min_inliers = config.wide.min_inliers;
  options.registration.max_position_sigma_m = config.wide.max_position_sigma_m;
  options.registration.msse.seed = static_cast<std::uint64_t>(config.seed);
  return options;
}

}  // namespace

WideCloser::WideCloser(const SlamConfig& config, const hal::Calibration& calibration, KeyframeStore& store,
                       const LoopCloser& loop_closer, Backend& backend, const wide::Vocabulary* vocabulary)
    : config_(config),
      store_(store),
      loop_closer_(loop_closer),
      backend_(backend),
      mapper_(calibration, mapper_options(config, vocabulary)) {
  candidates_.reserve(static_cast<std::size_t>(store.capacity()));
  chosen_.reserve(wide::WideResult::kMaxEdges);
  places_.reserve(static_cast<std::size_t>(store.capacity()));
  log_.resize(kLogCapacity);
}

void WideCloser::keyframe_stored(int slot) {
  keyframe_slot_ = slot;
  keyframe_has_image_ = false;
}

bool WideCloser::update(const cv::Mat& colour, const cv::Mat& depth, const cv::Mat* wide, bool tracked,
                        const Eigen::Isometry3d& T_world_cam) {
  const bool hand_over = wide != nullptr && tracked && !keyframe_has_image_ && keyframe_slot_ >= 0 &&
                         store_.slot(keyframe_slot_).used && store_.slot(keyframe_slot_).node >= 0;
  bool joined = false;
  if (!synchronous_ || hand_over) {
    if (synchronous_) mapper_.wait_idle();
    joined = take_results();
  }
  if (hand_over) {
    keyframe_has_image_ = true;
    submit(colour, depth, *wide, T_world_cam);
  }
  return joined;
}

bool WideCloser::finish() {
  mapper_.wait_idle();
  return take_results();
}

void WideCloser::submit(const cv::Mat& colour, const cv::Mat& depth, const cv::Mat& wide,
                        const Eigen::Isometry3d& T_world_cam) {
  const StoredKeyframe& current = store_.slot(keyframe_slot_);
  const Eigen::Isometry3d T_world_wide = T_world_cam * mapper_.T_rgb_wide();
  candidates_.clear();
  for (int i = 0; i < store_.capacity(); ++i) {
    const StoredKeyframe& stored = store_.slot(i);
    // The previous key-frame's registration to this one is the chain's own edge.
    if (!stored.used || i == keyframe_slot_ || stored.node < 0 || stored.sequence >= current.sequence - 1) continue;
    const double travelled_m = loop_closer_.travelled_m(current, stored);
    const double distance_m = (stored.T_world_cam.translation() - T_world_wide.translation()).norm();
    const double angle_deg =
        std::acos(std::clamp(stored.T_world_cam.linear().col(2).dot(T_world_wide.linear().col(2)), -1.0, 1.0)) *
        180.0 / M_PI;
    if (distance_m > config_.wide.search_radius_m + config_.loop.drift_per_m * travelled_m ||
        angle_deg > config_.wide.search_rotation_deg + config_.loop.drift_deg_per_m * travelled_m) {
      continue;
    }
    candidates_.push_back({distance_m, {i, stored.sequence}});
  }
  // Recent key-frames first, then the older ones a loop closure would look for: the nearest, and
  // the others to place recognition, nearest first.
  const auto recent_end = std::stable_partition(candidates_.begin(), candidates_.end(), [&](const Candidate& c) {
    return store_.slot(c.keyframe.slot).sequence > current.sequence - config_.loop.min_keyframe_gap;
  });
  chosen_.clear();
  const auto split = static_cast<std::size_t>(recent_end - candidates_.begin());
  choose(0, split, config_.wide.recent_candidates);
  std::sort(candidates_.begin() + static_cast<std::ptrdiff_t>(split), candidates_.end());
  const std::size_t nearest_end = split + static_cast<std::size_t>(std::max(config_.wide.loop_candidates, 0));
  places_.clear();
  for (std::size_t i = split; i < candidates_.size(); ++i) {
    if (i >= nearest_end) {
      places_.push_back(candidates_[i].keyframe);
    } else if (chosen_.size() < wide::WideResult::kMaxEdges) {
      chosen_.push_back(candidates_[i].keyframe);
    }
  }
  wide::WideSubmission submission;
  submission.colour = &colour;
  submission.depth = &depth;
  submission.wide = &wide;
  submission.keyframe = {keyframe_slot_, current.sequence};
  submission.T_keyframe_frame = current.T_world_cam.inverse() * T_world_cam;
  submission.candidates = chosen_;
  submission.places = places_;
  submission.place_count = config_.wide.place_candidates;
  ++counters_.images;
  if (!mapper_.submit(submission)) ++counters_.dropped;
}

void WideCloser::choose(std::size_t begin, std::size_t end, int count) {
  const std::size_t n = std::min(end - begin, static_cast<std::size_t>(std::max(count, 0)));
  const auto first = candidates_.begin() + static_cast<std::ptrdiff_t>(begin);
  std::partial_sort(first, first + static_cast<std::ptrdiff_t>(n), candidates_.begin() + static_cast<std::ptrdiff_t>(end));
  for (std::size_t i = 0; i < n && chosen_.size() < wide::WideResult::kMaxEdges; ++i) {
    chosen_.push_back(candidates_[begin + i].keyframe);
  }
}

bool WideCloser::take_results() {
  bool joined = false;
  mapper_.take_results([&](const wide::WideResult& result) { joined = apply_result(result) || joined; });
  return joined;
}

bool WideCloser::apply_result(const wide::WideResult& result) {
  const StoredKeyframe& current = store_.slot(result.keyframe.slot);
  if (!current.used || current.sequence != result.keyframe.sequence || current.node < 0) return false;
  bool joined = false;
  for (int e = 0; e < result.edge_count; ++e) {
    const wide::WideEdge& found = result.edges[static_cast<std::size_t>(e)];
    StoredKeyframe& stored = store_.slot(found.stored.slot);
    if (!stored.used || stored.sequence != found.stored.sequence || stored.node < 0) continue;
    // The edge-consistency check (ALGORITHMS.md §6.6): the edge may move the key-frame from the
    // chain's estimate no more than a loop closure may; between recent key-frames, whose chain
    // has drifted far less than the edge is uncertain, no more than its own uncertainty allows.
    const Eigen::Isometry3d chain = current.T_world_cam.inverse() * stored.T_world_cam;
    const Eigen::Isometry3d correction = chain.inverse() * found.T_keyframe_stored;
    const bool recent = stored.sequence > current.sequence - config_.loop.min_keyframe_gap;
    const lie::Vector6d residual = lie::log_so3_r3(found.T_keyframe_stored.inverse() * chain);
    if (!config_.loop.within_drift(correction.translation().norm(), lie::rotation_deg(correction),
                                   loop_closer_.travelled_m(current, stored)) ||
        (recent && residual.dot(found.information * residual) > kChiSquare6Dof99)) {
      ++counters_.refused;
      continue;
    }
    graph::Edge edge;
    edge.from = current.node;
    edge.to = stored.node;
    edge.T_from_to = lie::renormalised(found.T_keyframe_stored);
    edge.information = found.information;
    edge.kind = graph::EdgeKind::kLoopClosure;
    if (!backend_.add_loop_closure(edge)) continue;
    LoopClosure& logged = log_[static_cast<std::size_t>(counters_.edges % kLogCapacity)];
    logged.stored_stamp_s = stored.stamp_s;
    logged.current_stamp_s = current.stamp_s;
    logged.T_stored_current = edge.T_from_to.inverse();
    logged.photometric_inliers = found.inliers;
    logged.geometric_inliers = 0;
    logged.threshold = 0.0;
    ++counters_.edges;
    if (!recent) ++counters_.loop_edges;
    joined = true;
  }
  if (joined) ++counters_.mono_nodes;
  return joined;
}

}  // namespace rankslam::slam
