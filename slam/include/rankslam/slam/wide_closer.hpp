#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/slam/backend.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/loop_closer.hpp"
#include "rankslam/wide/wide_mapper.hpp"

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <vector>

namespace rankslam::slam {

/// What the wide-angle camera added to the map.
struct WideCounters {
  std::uint64_t images = 0;       ///< images handed to the mapper (one per key-frame at most)
  std::uint64_t dropped = 0;      ///< images the mapper's queue had no room for
  std::uint64_t mono_nodes = 0;   ///< images that registered to at least one stored key-frame
  std::uint64_t edges = 0;        ///< RGBD–mono edges in the pose graph
  std::uint64_t loop_edges = 0;   ///< of them, to key-frames older than loop_min_keyframe_gap
  std::uint64_t refused = 0;      ///< registrations the chain's consistency check refused
};

/// The wide-angle camera in the loop (docs/methods.md §14): at each key-frame the first paired
/// image of a frame tracked from it goes, with the frame's colour and depth, to the
/// wide::WideMapper, which registers it to the stored key-frames chosen here (the nearest recent
/// and older ones the wide-angle camera can see) and to the other older ones it can see whose
/// VLAD is most similar to the image's views (place recognition, ALGORITHMS.md §6.4); a registration that fits the chain as a loop
/// closure must (the edge-consistency check, ALGORITHMS.md §6.6) joins the pose graph as an edge
/// between the image's key-frame and the stored one. Everything is sized at construction.
class WideCloser {
 public:
  /// `calibration` must hold `fisheye`; the store, loop closer and back-end are the loop's.
  WideCloser(const SlamConfig& config, const hal::Calibration& calibration, KeyframeStore& store,
             const LoopCloser& loop_closer, Backend& backend, const wide::Vocabulary* vocabulary = nullptr);

  /// Offline replay: each image's registrations join the graph at the next key-frame's image,
  /// waiting for them, so the result does not depend on thread timing.
  void set_synchronous(bool synchronous) { synchronous_ = synchronous; }
  /// A new key-frame in `slot`: the next paired image is its.
  void keyframe_stored(int slot);
  /// Once per frame: the mapper's finished registrations join the graph (synchronous: only where
  /// an image is handed over), and a tracked frame's paired wide-angle image (`wide`, null: none)
  /// goes to the mapper when its key-frame has none yet. True when an edge joined the graph.
  bool update(const cv::Mat& colour, const cv::Mat& depth, const cv::Mat* wide, bool tracked,
              const Eigen::Isometry3d& T_world_cam);
  /// End of a run: waits for the mapper and takes what it found; true when an edge joined the graph.
  bool finish();
  [[nodiscard]] const WideCounters& counters() const { return counters_; }
  /// The index-th RGBD–mono edge (0: the first) as a closure between the two key-frames (its
  /// inliers as photometric ones), or null once it has left the log of the last kLogCapacity.
  [[nodiscard]] const LoopClosure* edge(std::uint64_t index) const {
    if (index >= counters_.edges || counters_.edges - index > kLogCapacity) return nullptr;
    return &log_[static_cast<std::size_t>(index % kLogCapacity)];
  }
  static constexpr std::uint64_t kLogCapacity = 64;

 private:
  struct Candidate {
    double distance_m = 0.0;
    wide::WideCandidate keyframe;
    bool operator<(const Candidate& other) const {
      return distance_m < other.distance_m ||
             (distance_m == other.distance_m && keyframe.slot < other.keyframe.slot);
    }
  };
  /// Hands the image to the mapper with the stored key-frames it may see.
  void submit(const cv::Mat& colour, const cv::Mat& depth, const cv::Mat& wide, const Eigen::Isometry3d& T_world_cam);
  /// Adds the nearest `count` of candidates_[begin, end) to chosen_.
  void choose(std::size_t begin, std::size_t end, int count);
  bool take_results();
  bool apply_result(const wide::WideResult& result);

  const SlamConfig& config_;
  KeyframeStore& store_;
  const LoopCloser& loop_closer_;
  Backend& backend_;
  wide::WideMapper mapper_;
  bool synchronous_ = false;
  int keyframe_slot_ = -1;
  bool keyframe_has_image_ = true;
  std::vector<Candidate> candidates_;
  std::vector<wide::WideCandidate> chosen_;
  std::vector<wide::WideCandidate> places_;
  WideCounters counters_;
  std::vector<LoopClosure> log_;
};

}  // namespace rankslam::slam
