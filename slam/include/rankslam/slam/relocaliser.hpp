#pragma once

#include "rankslam/slam/config.hpp"
#include "rankslam/slam/frame_result.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/orb_frontend.hpp"
#include "rankslam/slam/registrar.hpp"
#include "rankslam/slam/tracker.hpp"

#include <Eigen/Geometry>


namespace rankslam::slam {

/// Where a lost frame was found: its pose in the map and the stored key-frame it was registered
/// with.
struct Relocalisation {
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  int slot = -1;
  int inliers = 0;
  int photometric_inliers = 0;
  int geometric_inliers = 0;
  double noise_scale = 1.0;
};

/// Relocalisation (docs/methods.md §13): while searching, each frame is registered (photometric
/// and, in fused mode, geometric features) against a bounded number of stored key-frames, round
/// robin over the whole store. A registration that passes the loop-closure checks (the adaptive
/// threshold ε, inliers spread in two directions) and whose inliers fit their noise as a
/// tracking reference's must (reference_max_noise_scale) is the frame's hypothesis, the one with the
/// most inliers where several pass; it is taken once relocalise_confirm_frames consecutive
/// frames agree. Allocates nothing.
class Relocaliser {
 public:
  /// The store and registrar are the loop's and must outlive this.
  Relocaliser(const SlamConfig& config, const KeyframeStore& store, Registrar& registrar,
              geometry::GeometricFrontend& geometric);

  /// Forgets a search under way (the next search ranks the store afresh).
  void reset();
  /// Registers the frame against the stored key-frame in `slot` as the search does: true, with
  /// `found`, when the key-frame is usable and the registration passes the search's checks.
  [[nodiscard]] bool register_with(int slot, const TrackedFeatures& frame, double threshold, FrameResult& result,
                                   Relocalisation& found);
  /// One frame of the search: true, with `found`, once the frame's relocalisation is confirmed.
  /// `threshold` is the loop closer's ε. Adds to `result`'s stage times and candidate count.
  [[nodiscard]] bool search(const TrackedFeatures& frame, double threshold, FrameResult& result,
                            Relocalisation& found);

 private:
  /// A key-frame the frame can be registered with (its features of the same image kind).
  [[nodiscard]] bool usable(int slot, const PhotometricFeatures& features) const;
  /// Registers the frame against the key-frame in `slot`: true with `found` when it passes.
  /// The confirmed relocalisation refined as a loop closure is, on the found key-frame's cloud.
  void refine(const TrackedFeatures& frame, Relocalisation& found, FrameResult& result);
  [[nodiscard]] bool try_keyframe(int slot, const TrackedFeatures& frame, double threshold, Relocalisation& found,
                                  FrameResult& result);

  const SlamConfig& config_;
  const KeyframeStore& store_;
  Registrar& registrar_;
  geometry::GeometricFrontend& geometric_;
  /// The key-frame being registered, decoded from the store (StoredGeometry::decode).
  geometry::GeometricFeatures decoded_;
  int cursor_ = 0;
  /// The latest frames' agreeing relocalisations; the last one's pose and key-frame.
  int agreeing_ = 0;
  Eigen::Isometry3d T_world_last_ = Eigen::Isometry3d::Identity();
  int last_slot_ = 0;
};

}  // namespace rankslam::slam
