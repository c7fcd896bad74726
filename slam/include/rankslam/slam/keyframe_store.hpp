#pragma once

// The key-frames the back-end keeps (docs/methods.md §8, §10–§11): each stored key-frame's
// photometric and geometric features (for loop-closure registration), its map points in its own
// frame (so the map follows the optimised poses) and its pose-graph node. Every slot is
// allocated at construction; storing a key-frame copies into a free slot, and when none is free
// the store retires one (retirement_candidate()) so memory stays bounded.

#include "rankslam/geometry/frontend.hpp"
#include "rankslam/slam/orb_frontend.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace rankslam::slam {

/// A map point in its key-frame's camera frame, with its colour.
struct KeyframePoint {
  Eigen::Vector3f point_cam = Eigen::Vector3f::Zero();
  std::uint8_t blue = 0;
  std::uint8_t green = 0;
  std::uint8_t red = 0;
  /// Whether the live map took it (it refuses points once full): only those are taken out again.
  bool in_map = false;
};

/// A key-frame's geometric features as the store keeps them: keypoints and the thinned cloud as
/// extracted, but each SHOT descriptor as one byte a value with a scale (value ≈ code × scale,
/// the scale 1/255 of the descriptor's largest value: a quarter of the floats' memory, every
/// value within half a step) and each cloud normal as three 16-bit codes (component × 32767,
/// within 1.6e-5). Registrations read them decoded (decode()).
struct StoredGeometry {
  std::vector<Eigen::Vector3f> points_cam;
  std::vector<Eigen::Vector3f> normals;
  std::vector<float> sigma_m;
  std::vector<std::uint8_t> codes;  ///< count × kShotSize
  std::vector<float> scales;        ///< one per descriptor
  int count = 0;
  std::vector<Eigen::Vector3f> cloud_points;
  std::vector<std::array<std::int16_t, 3>> cloud_normals;
  std::vector<Eigen::Vector2f> cloud_pixels;
  std::vector<float> cloud_curvature;
  int cloud_count = 0;
  float resolution_m = 0.0F;
  float voxel_leaf_m = 0.0F;

  /// Set-up (allocates): room for `capacity` keypoints and `cloud_capacity` cloud points.
  void reserve(int capacity, int cloud_capacity);
  [[nodiscard]] int capacity() const { return static_cast<int>(sigma_m.size()); }
  [[nodiscard]] int cloud_capacity() const { return static_cast<int>(cloud_points.size()); }
  /// Set-up (allocates): features with room to decode these into.
  [[nodiscard]] geometry::GeometricFeatures make_decoded() const;
  /// The features as registrations take them, SHOT values restored from their codes (no
  /// allocation). False, `to` left empty, where `to` lacks the room.
  bool decode(geometry::GeometricFeatures& to) const;
  /// Copies another store's (no allocation; the room must be the same).
  void assign(const StoredGeometry& from);

  /// One descriptor's codes for its `kShotSize` values; returns the scale. Values that are not
  /// positive and finite are 0 (SHOT's are histograms); the scale is chosen so that decoding and
  /// encoding again gives the same codes and scale.
  static float encode(const float* values, std::uint8_t* codes);
  static void decode(const std::uint8_t* codes, float scale, float* values);
  /// A unit normal's codes (components clamped to [−1, 1]; not finite: 0) and back.
  static std::array<std::int16_t, 3> encode_normal(const Eigen::Vector3f& normal);
  static Eigen::Vector3f decode_normal(const std::array<std::int16_t, 3>& codes);
};

struct StoredKeyframe {
  bool used = false;
  /// Pose-graph node of the key-frame (its slot in the graph) and the node's generation.
  int node = -1;
  std::uint32_t generation = 0;
  /// Order of creation: tells the most recent key-frames apart.
  std::int64_t sequence = 0;
  /// The frame's capture time (hal::RgbdFrame::stamp_s).
  double stamp_s = 0.0;
  /// Camera pose: the tracking estimate, replaced by the optimised one.
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  /// Distance travelled by the camera (sum of key-frame to key-frame translations) when stored.
  double path_m = 0.0;
  /// Camera velocity when seen (angular, then linear; camera frame): its features' rolling-shutter
  /// correction in loop-closure registrations, as in tracking.
  Eigen::Matrix<double, 6, 1> velocity = Eigen::Matrix<double, 6, 1>::Zero();
  PhotometricFeatures photometric;
  StoredGeometry geometric;
  std::vector<KeyframePoint> points;
  int point_count = 0;
  /// The pose the points were put into the live map at (MapBuilder), to take them out again.
  Eigen::Isometry3d T_world_map = Eigen::Isometry3d::Identity();
  /// Loop closures this key-frame takes part in: the retirement policy keeps well-connected ones.
  int loop_closures = 0;
};

/// Fixed-capacity key-frame storage.
class KeyframeStore {
 public:
  /// Set-up (allocates): `capacity` slots, each with room for the given features, sampled-cloud
  /// points (for ICP-refined loop closures) and map points.
  KeyframeStore(int capacity, std::size_t photometric_capacity, int geometric_capacity, int cloud_points,
                int points_per_keyframe);

  [[nodiscard]] int capacity() const { return static_cast<int>(slots_.size()); }
  [[nodiscard]] int size() const { return size_; }
  [[nodiscard]] StoredKeyframe& slot(int index) { return slots_[static_cast<std::size_t>(index)]; }
  [[nodiscard]] const StoredKeyframe& slot(int index) const { return slots_[static_cast<std::size_t>(index)]; }

  /// A free slot, or -1 when the store is full.
  [[nodiscard]] int free_slot() const;
  /// Marks a slot used (its contents are the caller's to fill) / free.
  void occupy(int index);
  void release(int index);

  /// The slot to retire when the store is full: among key-frames at least `min_distance_m` from
  /// `T_world_current` and older than the `protect_recent` most recent ones, the one with the
  /// fewest loop closures, the oldest among equals. A key-frame with loop closures is kept while
  /// any without remains: those are the constraints that hold the map together. -1 when every
  /// key-frame is protected.
  [[nodiscard]] int retirement_candidate(const Eigen::Isometry3d& T_world_current, double min_distance_m,
                                         int protect_recent) const;

  /// Makes this store hold what `other` holds (no allocation; the stores must have been made
  /// with the same sizes): every slot's pose and links, and the features and points of the
  /// key-frames this store did not hold yet (told by their sequence), so copying again after a
  /// few new key-frames costs only those. False (nothing copied) when the capacities differ.
  bool copy_from(const KeyframeStore& other);
  /// Copies features into a slot (no allocation: the slot was sized at set-up; features beyond
  /// its capacity are dropped).
  static void copy_features(const PhotometricFeatures& from, PhotometricFeatures& to);
  static void copy_features(const geometry::GeometricFeatures& from, StoredGeometry& to);

 private:
  std::vector<StoredKeyframe> slots_;
  int size_ = 0;
};

/// The adaptive loop-closure threshold ε (docs/methods.md §10): ε = (μ_P − T_ε·σ_P) + (μ_G − T_ε·σ_G)
/// over the photometric and geometric inlier counts of the loop closures accepted so far; the
/// initial value until two closures exist, or always where it is not `adaptive` (the fixed
/// threshold the thesis compares against). A candidate closes the loop when k_P + k_G ≥ ε.
class AdaptiveLoopThreshold {
 public:
  AdaptiveLoopThreshold(double initial, double deviations, bool adaptive = true)
      : initial_(initial), deviations_(deviations), adaptive_(adaptive) {}

  [[nodiscard]] double value() const;
  /// Adds an accepted closure's inlier counts (running sums: no allocation).
  void add(int photometric_inliers, int geometric_inliers);
  [[nodiscard]] int count() const { return state_.count; }

  /// The running sums, saved and restored with the map (map_file.hpp).
  struct State {
    int count = 0;
    double sum_p = 0.0;
    double sum_sq_p = 0.0;
    double sum_g = 0.0;
    double sum_sq_g = 0.0;
  };
  [[nodiscard]] const State& state() const { return state_; }
  void restore(const State& saved) { state_ = saved; }

 private:
  double initial_;
  double deviations_;
  bool adaptive_;
  State state_;
};

}  // namespace rankslam::slam
