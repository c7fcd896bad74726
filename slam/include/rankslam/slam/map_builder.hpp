#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/frame_images.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/point_map.hpp"

#include <Eigen/Geometry>

#include <random>

namespace rankslam::slam {

/// The coloured point map: each key-frame adds points sampled at random pixels (as the thesis
/// samples its map), kept with the key-frame so the map can be rebuilt at optimised poses. The
/// map holds the stored key-frames' points: a retired key-frame's leave it, so the default
/// capacity, one key-frame store's worth, is never exceeded.
class MapBuilder {
 public:
  MapBuilder(const SlamConfig& config, const camera::DepthCameraModel& camera);

  /// slam.map_max_points, or where it is 0 the points of a full key-frame store.
  [[nodiscard]] static std::size_t capacity(const SlamConfig& config);

  /// Adds the key-frame `frame` at `T_world_cam`, coloured from the colour image or, without
  /// one, the IR image in `images`; the sampled points also go to `stored` when not null.
  void add_keyframe(const hal::RgbdFrame& frame, FrameImages& images, const Eigen::Isometry3d& T_world_cam,
                    StoredKeyframe* stored);
  /// Takes the key-frame's points out of the map (before it leaves the store).
  void remove_keyframe(StoredKeyframe& keyframe);
  /// Rebuilds the map from the stored key-frames at their poses, noting in each what it added.
  void rebuild(KeyframeStore& store);
  /// The same for a copy of a store (a checkpoint's), whose key-frames are not taken out again.
  void rebuild_copy(const KeyframeStore& store);

  [[nodiscard]] const PointMap& map() const { return map_; }

 private:
  void insert_all(const KeyframeStore& store, KeyframeStore* noted);

  const SlamConfig& config_;
  const camera::DepthCameraModel& camera_;
  PointMap map_;
  std::mt19937 sampler_;
};

}  // namespace rankslam::slam
