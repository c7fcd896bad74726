#pragma once

#include "rankslam/geometry/frontend.hpp"
#include "rankslam/slam/backend.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/frame_result.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/registrar.hpp"

#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace rankslam::slam {

/// Adaptive loop closure (docs/methods.md §10): a new key-frame is registered against the
/// nearest stored key-frames (all in its own frame, or a few per frame from then on); a
/// registration whose inliers pass the adaptive threshold ε (or tracking's minimum, where a
/// neighbour of the stored key-frame registers the new one to the same pose), whose correction
/// fits the drift since the candidate, whose inliers spread in two directions and which no
/// neighbour places elsewhere joins the pose graph.
/// Everything is sized at construction.
class LoopCloser {
 public:
  /// The store, registrar, front-end and back-end are the loop's and must outlive this.
  LoopCloser(const SlamConfig& config, KeyframeStore& store, Registrar& registrar,
             geometry::GeometricFrontend& geometric, Backend& backend);

  /// Set-up, fused mode: room to keep a searching key-frame's geometric features over frames.
  void keep_features_in(geometry::GeometricFeatures buffer) { search_copy_ = std::move(buffer); }

  /// Starts the search of the new key-frame in `slot`; `geometric` is the frame's own geometric
  /// features (null without geometry), kept where the search carries over into later frames.
  void start(int slot, const geometry::GeometricFeatures* geometric);
  /// Registers up to `count` pending candidates (all when 0); adds accepted closures to the graph.
  void advance(int count, FrameResult& result);

  [[nodiscard]] int closures() const { return closures_; }
  /// Closures that passed every other check and that the stored key-frame's neighbours refuted.
  [[nodiscard]] int refuted() const { return refuted_; }
  /// The index-th accepted closure, or null once it has left the log (see SlamLoop::loop_closure).
  [[nodiscard]] const LoopClosure* closure(int index) const;
  [[nodiscard]] double threshold() const { return threshold_.value(); }
  /// The adaptive threshold's state, saved and restored with the map.
  [[nodiscard]] AdaptiveLoopThreshold& adaptive_threshold() { return threshold_; }
  [[nodiscard]] const AdaptiveLoopThreshold& adaptive_threshold() const { return threshold_; }

  /// After a relocalisation onto a stored key-frame whose path length is `path_m`: the
  /// key-frames from `first_sequence` on continue the path from there (see travelled_m).
  void set_relocalisation(std::int64_t first_sequence, double path_m) {
    relocalised_first_sequence_ = first_sequence;
    relocalised_path_m_ = path_m;
  }
  /// The path along which drift accumulates between two key-frames: the distance travelled
  /// between them on one chain; from a key-frame made since the last relocalisation to an older
  /// one, the way through the key-frame relocalised onto (an older map's path lengths do not
  /// count the way from it to this chain).
  [[nodiscard]] double travelled_m(const StoredKeyframe& current, const StoredKeyframe& stored) const;

  static constexpr int kClosureLogMinCapacity = 64;

 private:
  /// Registers one candidate; adds it to the graph if it closes a loop.
  void try_candidate(StoredKeyframe& stored, FrameResult& result);
  /// The searching key-frame `current` registered against `stored`, predicted by `predicted`.
  struct StoredRegistration {
    MotionEstimate estimate;
    Eigen::Isometry3d T_stored_current = Eigen::Isometry3d::Identity();  ///< refined where it was
    int photometric_inliers = 0;
    int geometric_inliers = 0;
    bool refined_by_icp = false;
  };
  /// Registers as a closure is measured: false unless the inliers reach `min_inliers`, where
  /// tracking would need the ICP the refinement on the stored cloud holds, and the pose found
  /// moves `current` from the chain's pose no more than the drift since `stored` allows.
  [[nodiscard]] bool register_stored(const StoredKeyframe& stored, const StoredKeyframe& current,
                                     const Eigen::Isometry3d& predicted, double min_inliers,
                                     StoredRegistration& out);
  /// Whether two poses lie within loop_neighbour_agreement_m and _deg of each other.
  [[nodiscard]] bool agree(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) const;
  /// What a registration of the searching key-frame against `neighbour`, a key-frame beside the
  /// closure's stored one in the chain, says of the closure's pose `T_neighbour_current`: with
  /// `min_inliers`, whether it agrees; with tracking's minimum, only that it disagrees where it
  /// keeps the chain's pose and the closure moves it (`closure_moves`).
  enum class Witness { kNone, kAgrees, kDisagrees };
  [[nodiscard]] Witness witness(const StoredKeyframe& neighbour, const StoredKeyframe& current,
                                const Eigen::Isometry3d& T_neighbour_current, double min_inliers,
                                bool closure_moves);
  /// What the chain around `stored` says of the closure T_stored_current: the key-frames next to
  /// it in sequence register the new one with `min_inliers`; kAgrees where one places it where
  /// the closure does, kDisagrees where one or both registered and none agreed (or one with
  /// tracking's minimum keeps the chain's pose the closure moves), kNone where neither did.
  [[nodiscard]] Witness neighbours_say(const StoredKeyframe& stored, const StoredKeyframe& current,
                                       const Eigen::Isometry3d& T_stored_current, double min_inliers);

  /// A stored key-frame near the searching one: the nearest are registered first.
  struct Candidate {
    double distance_m = 0.0;
    int slot = -1;
    std::int64_t sequence = 0;  ///< the slot's key-frame when chosen (it may be retired since)
    bool operator<(const Candidate& other) const {
      return distance_m < other.distance_m || (distance_m == other.distance_m && slot < other.slot);
    }
  };

  const SlamConfig& config_;
  KeyframeStore& store_;
  Registrar& registrar_;
  geometry::GeometricFrontend& geometric_;
  Backend& backend_;
  AdaptiveLoopThreshold threshold_;
  /// The search under way: its key-frame, its candidates, nearest first, up to
  /// loop_max_candidates of them, and the next one to register.
  std::vector<Candidate> candidates_;
  std::size_t tried_ = 0;
  std::size_t next_ = 0;
  int search_slot_ = -1;
  std::int64_t search_sequence_ = 0;
  /// The searching key-frame's features as extracted (the store keeps a thinned cloud and no
  /// block means, which the ICP refinement of a closure uses): the frame's own while the search
  /// ends in its frame, else search_copy_; null without geometry.
  const geometry::GeometricFeatures* search_geometric_ = nullptr;
  geometry::GeometricFeatures search_copy_;
  /// The two key-frames of a registration decoded from the store (StoredGeometry::decode); the
  /// current one, by its sequence (0: none), is decoded again only when the key-frame changes.
  geometry::GeometricFeatures stored_decoded_;
  geometry::GeometricFeatures current_decoded_;
  std::int64_t current_decoded_sequence_ = 0;
  int closures_ = 0;
  int refuted_ = 0;
  std::int64_t relocalised_first_sequence_ = 0;
  double relocalised_path_m_ = 0.0;
  /// The latest accepted closures, by index modulo the size.
  std::vector<LoopClosure> log_;
};

}  // namespace rankslam::slam
