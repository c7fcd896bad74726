#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/graph/local_bundle.hpp"
#include "rankslam/graph/pose_graph.hpp"
#include "rankslam/parallel/companion.hpp"
#include "rankslam/slam/backend.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/orb_frontend.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <vector>

namespace rankslam::slam {

/// What local mapping did so far.
struct LocalMapCounters {
  /// Windows adjusted, and those whose solve failed.
  int adjustments = 0;
  int failed = 0;
  /// Registration edges replaced by the adjustment's estimate.
  int refined_edges = 0;
  /// Landmarks and their observations in the latest adjustment, and those inside the Huber
  /// threshold after it.
  int landmarks = 0;
  int observations = 0;
  int inlier_observations = 0;
  /// Mapping-thread time of all adjustments (matching, landmarks, solve), ms.
  double adjust_ms = 0.0;
};

/// Local mapping (docs/methods.md §18). At each stored key-frame the newest `local.window`
/// key-frames are copied (their ORB features with depth, rolling-shutter corrected as tracking
/// registers them, their noise and their poses) and handed to the mapping thread, which matches
/// the features of every pair into landmarks (mutual Hamming matches that lie where the poses put
/// them, within the points' noise and `local.match_radius_px`; a landmark seen twice in one
/// key-frame is dropped) and adjusts poses and landmarks together, the graph's registration,
/// planar and wheel edges between those key-frames joining as priors (graph::LocalBundle). Each
/// registration edge takes the adjusted motion once: when it is the oldest of a full window, and
/// only where its two key-frames share at least `min_inliers` landmarks within the Huber
/// threshold (the newest window's other edges keep their registrations). The pose graph spreads
/// it.
///
/// Every buffer is sized at construction; handing a window over and taking the result allocate
/// nothing; the adjustment's Ceres solve allocates on the mapping thread.
class LocalMapper {
 public:
  /// Set-up (allocates, starts the mapping thread when on): key-frames with up to
  /// `features_per_keyframe` photometric features. Throws std::invalid_argument naming
  /// slam.local_window where the thread cannot start.
  LocalMapper(const SlamConfig& config, const camera::DepthCameraModel& camera, std::size_t features_per_keyframe);

  [[nodiscard]] bool enabled() const { return window_ >= 2; }
  /// Offline replay: adjust on the caller's schedule (results independent of thread timing).
  void set_synchronous(bool synchronous) { synchronous_ = synchronous; }

  /// At a stored key-frame: hands the newest window of `store` with the edges of `graph` between
  /// its key-frames to the mapping thread. False (nothing handed over) when off, while the
  /// previous window is being adjusted or its result not taken, or with fewer than two
  /// key-frames with features.
  bool submit(const KeyframeStore& store, const graph::PoseGraph& graph);
  /// A finished adjustment's refined edges written into the back-end's graph where their
  /// key-frames are still the same nodes; how many. 0 when none finished (`wait`: waits for
  /// one under way, at the end of a run).
  int take(Backend& backend, bool wait = false);
  /// End of a run: takes the adjustment under way (waits for it).
  void finish(Backend& backend);

  [[nodiscard]] const LocalMapCounters& counters() const { return counters_; }

 private:
  struct WindowFrame {
    int node = -1;
    std::uint32_t generation = 0;
    std::int64_t sequence = 0;
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    int count = 0;
    std::vector<Eigen::Vector3f> points_cam;
    std::vector<float> sigma_m;
    cv::Mat descriptors;  ///< room for every feature; the first `count` rows hold them
  };
  struct WindowEdge {
    int from = 0;
    int to = 0;
    Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
    graph::LocalBundle::Matrix6d information = graph::LocalBundle::Matrix6d::Identity();
  };

  /// Mapping thread: adjust_window(), timed.
  void adjust();
  /// Landmarks, adjustment, refined edges.
  void adjust_window();
  struct Job {
    LocalMapper* mapper;
    void operator()() const { mapper->adjust(); }
  };
  /// Joins the pairs' gated matches into tracks (union-find over window feature slots).
  void associate();
  [[nodiscard]] int find_root(int slot);

  const SlamConfig& config_;
  const camera::DepthCameraModel& camera_;
  const int window_;
  const int features_;  ///< per key-frame
  bool synchronous_ = false;
  /// A window is with the mapping thread (or its result not taken yet).
  bool submitted_ = false;

  // The window, copied at submit(); read and written by the mapping thread until take().
  std::vector<WindowFrame> frames_;
  int frame_count_ = 0;
  std::vector<WindowEdge> edges_;
  int edge_count_ = 0;
  bool adjusted_ = false;
  /// The adjusted motion of the window's oldest edge, where the adjustment refines it.
  bool oldest_refined_ = false;
  Eigen::Isometry3d T_oldest_next_ = Eigen::Isometry3d::Identity();
  /// The newest key-frame (by sequence) whose edge from the one before was considered for
  /// refinement; the mapping thread's, read and written only while it holds a window.
  std::int64_t considered_through_ = 0;
  /// The window's figures (only landmarks, observations, inliers and time are set).
  LocalMapCounters adjustment_;

  /// A pair of key-frames' mutual matches, kept while both stay in the window: they depend on
  /// the descriptors only, and the window moves by one key-frame at a time.
  struct PairMatches {
    std::int64_t first = -1;  ///< the key-frames' sequences, first older
    std::int64_t second = -1;
    bool live = false;  ///< a pair of the window being associated
    std::vector<FeatureMatch> matches;
  };
  /// The pair's matches: cached, or matched into a slot no pair of the window holds.
  const std::vector<FeatureMatch>& pair_matches(const WindowFrame& first, const WindowFrame& second);

  // Mapping-thread scratch.
  MutualHammingMatcher matcher_;
  std::vector<PairMatches> pairs_;  ///< a slot per pair of a full window
  std::vector<int> parent_;              ///< per feature slot (frame · features + index)
  std::vector<std::uint32_t> frames_seen_;  ///< per root: a bit per window frame
  std::vector<std::uint8_t> conflicted_;   ///< per root: two features of one frame
  std::vector<int> landmark_of_;           ///< per root: its landmark, or −1
  std::vector<Eigen::Vector3d> landmark_sum_;
  std::vector<int> landmark_count_;
  std::vector<std::uint32_t> inlier_frames_;  ///< per landmark: a bit per frame seeing it as an inlier
  graph::LocalBundle bundle_;

  LocalMapCounters counters_;
  // Last, so that it stops (finishing a window under way) before what the window uses goes.
  parallel::Companion thread_;
  Job job_{this};
};

}  // namespace rankslam::slam
