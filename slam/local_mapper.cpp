#include "rankslam/slam/local_mapper.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/stopwatch.hpp"
#include "rankslam/slam/registration_support.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace rankslam::slam {
namespace {

// Edges a window may hold: a registration, planar and wheel edge per consecutive pair, and room
// for edges composed through retired key-frames.
constexpr int kEdgesPerFrame = 4;
// The configuration's largest window (slam.local_window); a frame is a bit of a 32-bit mask.
constexpr int kMaxWindow = 16;

}  // namespace

LocalMapper::LocalMapper(const SlamConfig& config, const camera::DepthCameraModel& camera,
                         std::size_t features_per_keyframe)
    : config_(config),
      camera_(camera),
      window_(config.local.window >= 2 && features_per_keyframe > 0 ? config.local.window : 0),
      features_(static_cast<int>(features_per_keyframe)) {
  if (!enabled()) return;
  frames_.resize(static_cast<std::size_t>(window_));
  for (WindowFrame& frame : frames_) {
    frame.points_cam.assign(features_per_keyframe, Eigen::Vector3f::Zero());
    frame.sigma_m.assign(features_per_keyframe, 0.0F);
    frame.descriptors.create(features_, 32, CV_8UC1);
  }
  edges_.resize(static_cast<std::size_t>(kEdgesPerFrame * window_));
  const std::size_t slots = static_cast<std::size_t>(window_) * features_per_keyframe;
  matcher_.reserve(features_per_keyframe);
  pairs_.resize(static_cast<std::size_t>(window_ * (window_ - 1) / 2));
  for (PairMatches& pair : pairs_) pair.matches.reserve(features_per_keyframe);
  parent_.assign(slots, 0);
  frames_seen_.assign(slots, 0);
  conflicted_.assign(slots, 0);
  landmark_of_.assign(slots, -1);
  // A landmark is seen at least twice.
  const std::size_t max_landmarks = slots / 2;
  landmark_sum_.assign(max_landmarks, Eigen::Vector3d::Zero());
  landmark_count_.assign(max_landmarks, 0);
  inlier_frames_.assign(max_landmarks, 0);
  const std::string error = bundle_.configure({window_, static_cast<int>(max_landmarks), static_cast<int>(slots),
                                               kEdgesPerFrame * window_});
  if (!error.empty()) throw std::invalid_argument("slam.local_window: " + error);
  if (const std::string started = thread_.start(); !started.empty()) {
    throw std::invalid_argument("slam.local_window: " + started);
  }
}

void LocalMapper::finish(Backend& backend) { (void)take(backend, true); }

bool LocalMapper::submit(const KeyframeStore& store, const graph::PoseGraph& graph) {
  if (!enabled() || submitted_) return false;
  // The newest key-frames with a node and features: each the newest older than the last taken.
  std::array<int, kMaxWindow> newest{};
  int chosen = 0;
  for (std::int64_t below = INT64_MAX; chosen < window_; ++chosen) {
    int found = -1;
    for (int slot = 0; slot < store.capacity(); ++slot) {
      const StoredKeyframe& keyframe = store.slot(slot);
      const bool eligible = keyframe.used && keyframe.node >= 0 && keyframe.photometric.size() > 0;
      if (!eligible || keyframe.sequence >= below) continue;
      if (found < 0 || keyframe.sequence > store.slot(found).sequence) found = slot;
    }
    if (found < 0) break;
    newest[static_cast<std::size_t>(chosen)] = found;
    below = store.slot(found).sequence;
  }
  std::reverse(newest.begin(), newest.begin() + chosen);  // oldest first
  if (chosen < 2) return false;
  frame_count_ = chosen;
  for (int k = 0; k < chosen; ++k) {
    const StoredKeyframe& keyframe = store.slot(newest[static_cast<std::size_t>(k)]);
    WindowFrame& frame = frames_[static_cast<std::size_t>(k)];
    frame.node = keyframe.node;
    frame.generation = keyframe.generation;
    frame.sequence = keyframe.sequence;
    frame.T_world_cam = keyframe.T_world_cam;
    const PhotometricFeatures& features = keyframe.photometric;
    frame.count = std::min(static_cast<int>(features.size()), features_);
    for (int i = 0; i < frame.count; ++i) {
      const auto index = static_cast<std::size_t>(i);
      // As tracking registers them: in the frame's mid-exposure camera pose, with their noise.
      frame.points_cam[index] =
          rolling_shutter_corrected(features.points_cam[index], features.keypoints[index].pt.y, camera_.height(),
                                    config_.rolling_shutter_readout_ms * 1e-3, keyframe.velocity);
      frame.sigma_m[index] = features.sigma_m[index];
    }
    if (frame.count > 0) features.descriptors.rowRange(0, frame.count).copyTo(frame.descriptors.rowRange(0, frame.count));
  }
  // The graph's edges among them, loop closures aside: those the pose graph weighs itself.
  edge_count_ = 0;
  const auto index_of = [&](int node) {
    for (int k = 0; k < frame_count_; ++k) {
      if (frames_[static_cast<std::size_t>(k)].node == node) return k;
    }
    return -1;
  };
  for (int e = 0; e < graph.edge_count() && edge_count_ < static_cast<int>(edges_.size()); ++e) {
    const graph::Edge& edge = graph.edge(e);
    if (edge.kind == graph::EdgeKind::kLoopClosure) continue;
    const int from = index_of(edge.from);
    const int to = index_of(edge.to);
    if (from < 0 || to < 0) continue;
    edges_[static_cast<std::size_t>(edge_count_++)] = {from, to, edge.T_from_to, edge.information};
  }
  adjusted_ = false;
  oldest_refined_ = false;
  submitted_ = true;
  thread_.launch(job_);
  if (synchronous_) thread_.wait();
  return true;
}

int LocalMapper::take(Backend& backend, bool wait) {
  if (!submitted_) return 0;
  if (!wait && !synchronous_ && !thread_.idle()) return 0;
  thread_.wait();
  submitted_ = false;
  ++counters_.adjustments;
  counters_.landmarks = adjustment_.landmarks;
  counters_.observations = adjustment_.observations;
  counters_.inlier_observations = adjustment_.inlier_observations;
  counters_.adjust_ms += adjustment_.adjust_ms;
  if (!adjusted_) {
    ++counters_.failed;
    return 0;
  }
  if (!oldest_refined_) return 0;
  const WindowFrame& oldest = frames_[0];
  const WindowFrame& next = frames_[1];
  if (!backend.refine_sequential_edge(oldest.node, oldest.generation, next.node, next.generation, T_oldest_next_)) {
    return 0;
  }
  ++counters_.refined_edges;
  return 1;
}

int LocalMapper::find_root(int slot) {
  int root = slot;
  while (parent_[static_cast<std::size_t>(root)] != root) root = parent_[static_cast<std::size_t>(root)];
  while (parent_[static_cast<std::size_t>(slot)] != root) {
    const int next = parent_[static_cast<std::size_t>(slot)];
    parent_[static_cast<std::size_t>(slot)] = root;
    slot = next;
  }
  return root;
}

void LocalMapper::associate() {
  for (int k = 0; k < frame_count_; ++k) {
    for (int i = 0; i < frames_[static_cast<std::size_t>(k)].count; ++i) {
      const int slot = k * features_ + i;
      parent_[static_cast<std::size_t>(slot)] = slot;
    }
  }
  const auto fx = static_cast<float>(camera_.calibration().fx);
  const auto radius_px = static_cast<float>(config_.local.match_radius_px);
  // The cached pairs this window still holds (frames_ is oldest first, as each window).
  const auto in_window = [&](std::int64_t sequence) {
    for (int k = 0; k < frame_count_; ++k) {
      if (frames_[static_cast<std::size_t>(k)].sequence == sequence) return true;
    }
    return false;
  };
  for (PairMatches& pair : pairs_) pair.live = pair.first >= 0 && in_window(pair.first) && in_window(pair.second);
  for (int a = 0; a < frame_count_; ++a) {
    const WindowFrame& first = frames_[static_cast<std::size_t>(a)];
    for (int b = a + 1; b < frame_count_; ++b) {
      const WindowFrame& second = frames_[static_cast<std::size_t>(b)];
      if (first.count == 0 || second.count == 0) continue;
      const Eigen::Isometry3f T_first_second = (first.T_world_cam.inverse() * second.T_world_cam).cast<float>();
      for (const FeatureMatch& match : pair_matches(first, second)) {
        const Eigen::Vector3f& p = first.points_cam[match.source];
        const Eigen::Vector3f q = T_first_second * second.points_cam[match.target];
        const float sigma_p = first.sigma_m[match.source];
        const float sigma_q = second.sigma_m[match.target];
        const float gate_m =
            static_cast<float>(kInlierSigmas) * std::sqrt(sigma_p * sigma_p + sigma_q * sigma_q) + radius_px * p.z() / fx;
        if ((p - q).squaredNorm() > gate_m * gate_m) continue;
        const int root_p = find_root(a * features_ + static_cast<int>(match.source));
        const int root_q = find_root(b * features_ + static_cast<int>(match.target));
        if (root_p == root_q) continue;
        parent_[static_cast<std::size_t>(std::max(root_p, root_q))] = std::min(root_p, root_q);
      }
    }
  }
}

const std::vector<FeatureMatch>& LocalMapper::pair_matches(const WindowFrame& first, const WindowFrame& second) {
  PairMatches* free = nullptr;
  for (PairMatches& pair : pairs_) {
    if (pair.live && pair.first == first.sequence && pair.second == second.sequence) return pair.matches;
    if (!pair.live && free == nullptr) free = &pair;
  }
  // A window's pairs are at most the slots, and each live slot is one of them: one is free.
  free->first = first.sequence;
  free->second = second.sequence;
  free->live = true;
  matcher_.match(first.descriptors.rowRange(0, first.count), second.descriptors.rowRange(0, second.count),
                 config_.max_hamming_distance, free->matches);
  return free->matches;
}

void LocalMapper::adjust() {
  const auto start = SteadyClock::now();
  adjust_window();
  adjustment_.adjust_ms = elapsed_ms(start);
}

void LocalMapper::adjust_window() {
  associate();
  // Tracks: the window frames each root's features come from; a track with two features of one
  // frame joined different points (a repeated texture) and is dropped.
  for (int k = 0; k < frame_count_; ++k) {
    for (int i = 0; i < frames_[static_cast<std::size_t>(k)].count; ++i) {
      const auto slot = static_cast<std::size_t>(k * features_ + i);
      frames_seen_[slot] = 0;
      conflicted_[slot] = 0;
      landmark_of_[slot] = -1;
    }
  }
  for (int k = 0; k < frame_count_; ++k) {
    for (int i = 0; i < frames_[static_cast<std::size_t>(k)].count; ++i) {
      const auto root = static_cast<std::size_t>(find_root(k * features_ + i));
      const std::uint32_t bit = 1U << static_cast<unsigned>(k);
      if ((frames_seen_[root] & bit) != 0) conflicted_[root] = 1;
      frames_seen_[root] |= bit;
    }
  }
  const int max_landmarks = static_cast<int>(landmark_sum_.size());
  int landmarks = 0;
  for (int k = 0; k < frame_count_; ++k) {
    for (int i = 0; i < frames_[static_cast<std::size_t>(k)].count; ++i) {
      const int slot = k * features_ + i;
      const auto root = static_cast<std::size_t>(find_root(slot));
      if (landmark_of_[root] < 0) {
        if (conflicted_[root] != 0 || std::popcount(frames_seen_[root]) < 2 || landmarks == max_landmarks) continue;
        landmark_sum_[static_cast<std::size_t>(landmarks)].setZero();
        landmark_count_[static_cast<std::size_t>(landmarks)] = 0;
        landmark_of_[root] = landmarks++;
      }
      const auto landmark = static_cast<std::size_t>(landmark_of_[root]);
      const WindowFrame& frame = frames_[static_cast<std::size_t>(k)];
      landmark_sum_[landmark] += frame.T_world_cam * frame.points_cam[static_cast<std::size_t>(i)].cast<double>();
      ++landmark_count_[landmark];
    }
  }
  bundle_.clear();
  for (int k = 0; k < frame_count_; ++k) (void)bundle_.add_pose(frames_[static_cast<std::size_t>(k)].T_world_cam);
  for (int l = 0; l < landmarks; ++l) {
    (void)bundle_.add_landmark(landmark_sum_[static_cast<std::size_t>(l)] / landmark_count_[static_cast<std::size_t>(l)]);
  }
  for (int k = 0; k < frame_count_; ++k) {
    const WindowFrame& frame = frames_[static_cast<std::size_t>(k)];
    for (int i = 0; i < frame.count; ++i) {
      const int landmark = landmark_of_[static_cast<std::size_t>(find_root(k * features_ + i))];
      if (landmark < 0) continue;
      const auto index = static_cast<std::size_t>(i);
      // The noise model tracking registers with (PhotometricFeatures::sigma_m).
      const Eigen::Matrix3d whitening = Eigen::Matrix3d::Identity() / double{frame.sigma_m[index]};
      (void)bundle_.add_observation(k, landmark, frame.points_cam[index].cast<double>(), whitening);
    }
  }
  const int observations = bundle_.observations();
  for (int e = 0; e < edge_count_; ++e) {
    const WindowEdge& edge = edges_[static_cast<std::size_t>(e)];
    (void)bundle_.add_edge(edge.from, edge.to, edge.T_from_to, edge.information);
  }
  const graph::LocalBundleSummary summary = bundle_.solve(config_.local.iterations, config_.local.huber);
  adjustment_.landmarks = landmarks;
  adjustment_.observations = observations;
  adjustment_.inlier_observations = summary.inlier_observations;
  if (!summary.ok) return;
  for (int l = 0; l < landmarks; ++l) inlier_frames_[static_cast<std::size_t>(l)] = 0;
  for (int o = 0; o < observations; ++o) {
    if (!bundle_.inlier(o)) continue;
    inlier_frames_[static_cast<std::size_t>(bundle_.observation_landmark(o))] |=
        1U << static_cast<unsigned>(bundle_.observation_pose(o));
  }
  // A registration edge takes the adjusted motion once (considered_through_: the newest key-frame
  // whose incoming edge was considered), when it is the window's oldest in a full window (every
  // later key-frame that sees its landmarks has joined; the next windows no longer hold it, so
  // its landmarks are not counted twice), and only where landmarks tie its two key-frames as
  // firmly as a registration needs. The newer edges' landmarks are seen by fewer key-frames: at
  // the end of a run they keep their registrations.
  adjusted_ = true;
  if (frame_count_ < window_ || frames_[1].sequence <= considered_through_) return;
  considered_through_ = frames_[1].sequence;
  constexpr std::uint32_t kOldestTwo = 0b11U;
  int shared = 0;
  for (int l = 0; l < landmarks; ++l) {
    shared += (inlier_frames_[static_cast<std::size_t>(l)] & kOldestTwo) == kOldestTwo ? 1 : 0;
  }
  if (shared < config_.min_inliers) return;
  oldest_refined_ = true;
  T_oldest_next_ = lie::renormalised(bundle_.pose(0).inverse() * bundle_.pose(1));
}

}  // namespace rankslam::slam
