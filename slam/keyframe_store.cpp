#include "rankslam/slam/keyframe_store.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace rankslam::slam {

KeyframeStore::KeyframeStore(int capacity, std::size_t photometric_capacity, int geometric_capacity, int cloud_points,
                             int points_per_keyframe)
    : slots_(static_cast<std::size_t>(std::max(0, capacity))) {
  for (StoredKeyframe& keyframe : slots_) {
    keyframe.photometric.reserve(photometric_capacity);
    // Keypoints, descriptors and the sampled cloud: loop closure matches descriptors and refines
    // weak closures by ICP against the cloud; the dense block means come from the current frame.
    keyframe.geometric.reserve(geometric_capacity, geometric_capacity > 0 ? cloud_points : 0);
    keyframe.points.assign(static_cast<std::size_t>(std::max(0, points_per_keyframe)), KeyframePoint{});
  }
}

int KeyframeStore::free_slot() const {
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    if (!slots_[i].used) return static_cast<int>(i);
  }
  return -1;
}

void KeyframeStore::occupy(int index) {
  StoredKeyframe& keyframe = slot(index);
  if (!keyframe.used) ++size_;
  keyframe.used = true;
  keyframe.loop_closures = 0;
  keyframe.point_count = 0;
  keyframe.node = -1;
}

void KeyframeStore::release(int index) {
  StoredKeyframe& keyframe = slot(index);
  if (keyframe.used) --size_;
  keyframe.used = false;
  keyframe.node = -1;
}

int KeyframeStore::retirement_candidate(const Eigen::Isometry3d& T_world_current, double min_distance_m,
                                        int protect_recent) const {
  std::int64_t newest = 0;
  for (const StoredKeyframe& keyframe : slots_) {
    if (keyframe.used) newest = std::max(newest, keyframe.sequence);
  }
  int best = -1;
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    const StoredKeyframe& keyframe = slots_[i];
    if (!keyframe.used || keyframe.sequence > newest - protect_recent) continue;
    if ((keyframe.T_world_cam.translation() - T_world_current.translation()).norm() < min_distance_m) continue;
    if (best < 0) {
      best = static_cast<int>(i);
      continue;
    }
    const StoredKeyframe& chosen = slots_[static_cast<std::size_t>(best)];
    if (keyframe.loop_closures < chosen.loop_closures ||
        (keyframe.loop_closures == chosen.loop_closures && keyframe.sequence < chosen.sequence)) {
      best = static_cast<int>(i);
    }
  }
  return best;
}

bool KeyframeStore::copy_from(const KeyframeStore& other) {
  if (other.slots_.size() != slots_.size()) return false;
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    const StoredKeyframe& from = other.slots_[i];
    StoredKeyframe& to = slots_[i];
    if (!from.used) {
      to.used = false;
      continue;
    }
    // A key-frame's features and points are fixed once stored; its pose and links are not.
    if (!to.used || to.sequence != from.sequence || to.point_count != from.point_count) {
      copy_features(from.photometric, to.photometric);
      to.geometric.assign(from.geometric);
      const auto points = std::min(from.points.size(), to.points.size());
      to.point_count = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(from.point_count), points));
      std::copy_n(from.points.begin(), to.point_count, to.points.begin());
    }
    to.used = true;
    to.node = from.node;
    to.generation = from.generation;
    to.sequence = from.sequence;
    to.stamp_s = from.stamp_s;
    to.T_world_cam = from.T_world_cam;
    to.path_m = from.path_m;
    to.velocity = from.velocity;
    to.loop_closures = from.loop_closures;
  }
  size_ = other.size_;
  return true;
}

void KeyframeStore::copy_features(const PhotometricFeatures& from, PhotometricFeatures& to) {
  to.clear();
  const auto n = static_cast<int>(std::min({from.size(), to.keypoints.capacity(), to.points_cam.capacity(),
                                            static_cast<std::size_t>(to.descriptor_storage.rows)}));
  to.keypoints.assign(from.keypoints.begin(), from.keypoints.begin() + n);
  to.points_cam.assign(from.points_cam.begin(), from.points_cam.begin() + n);
  to.sigma_m.assign(from.sigma_m.begin(), from.sigma_m.begin() + n);
  for (int i = 0; i < n; ++i) std::memcpy(to.descriptor_storage.ptr(i), from.descriptors.ptr(i), 32);
  to.descriptors = to.descriptor_storage.rowRange(0, n);
  to.source = from.source;
}

void KeyframeStore::copy_features(const geometry::GeometricFeatures& from, StoredGeometry& to) {
  const int n = std::min(from.count, to.capacity());
  std::copy_n(from.points_cam.begin(), n, to.points_cam.begin());
  std::copy_n(from.normals.begin(), n, to.normals.begin());
  std::copy_n(from.sigma_m.begin(), n, to.sigma_m.begin());
  for (int i = 0; i < n; ++i) {
    to.scales[static_cast<std::size_t>(i)] =
        StoredGeometry::encode(from.descriptor(i), to.codes.data() + static_cast<std::ptrdiff_t>(i) * geometry::kShotSize);
  }
  to.count = n;
  // The sampled cloud, evenly strided down to the room kept (the ICP associates projectively, so
  // a thinned target still covers the view).
  const int room = static_cast<int>(to.cloud_points.size());
  to.cloud_count = 0;
  if (room > 0 && from.cloud_count > 0) {
    const int stride = (from.cloud_count + room - 1) / room;
    for (int i = 0; i < from.cloud_count; i += stride) {
      const auto a = static_cast<std::size_t>(i);
      const auto b = static_cast<std::size_t>(to.cloud_count++);
      to.cloud_points[b] = from.cloud_points[a];
      to.cloud_normals[b] = StoredGeometry::encode_normal(from.cloud_normals[a]);
      to.cloud_pixels[b] = from.cloud_pixels[a];
      to.cloud_curvature[b] = from.cloud_curvature[a];
    }
  }
  to.resolution_m = from.resolution_m;
  to.voxel_leaf_m = from.voxel_leaf_m;
}

void StoredGeometry::reserve(int capacity, int cloud_capacity) {
  const auto n = static_cast<std::size_t>(std::max(0, capacity));
  points_cam.assign(n, Eigen::Vector3f::Zero());
  normals.assign(n, Eigen::Vector3f::Zero());
  sigma_m.assign(n, 0.0F);
  codes.assign(n * static_cast<std::size_t>(geometry::kShotSize), 0);
  scales.assign(n, 0.0F);
  count = 0;
  const auto m = static_cast<std::size_t>(std::max(0, cloud_capacity));
  cloud_points.assign(m, Eigen::Vector3f::Zero());
  cloud_normals.assign(m, std::array<std::int16_t, 3>{});
  cloud_pixels.assign(m, Eigen::Vector2f::Zero());
  cloud_curvature.assign(m, 0.0F);
  cloud_count = 0;
}

geometry::GeometricFeatures StoredGeometry::make_decoded() const {
  geometry::GeometricFeatures features;
  features.reserve(capacity(), cloud_capacity(), 0);
  return features;
}

bool StoredGeometry::decode(geometry::GeometricFeatures& to) const {
  to.count = to.cloud_count = to.block_count = 0;
  if (count > to.capacity() || cloud_count > static_cast<int>(to.cloud_points.size())) return false;
  const auto n = static_cast<std::size_t>(count);
  std::copy_n(points_cam.begin(), n, to.points_cam.begin());
  std::copy_n(normals.begin(), n, to.normals.begin());
  std::copy_n(sigma_m.begin(), n, to.sigma_m.begin());
  for (std::size_t i = 0; i < n; ++i) {
    const auto offset = static_cast<std::ptrdiff_t>(i) * geometry::kShotSize;
    decode(codes.data() + offset, scales[i], to.descriptors.data() + offset);
  }
  const auto m = static_cast<std::size_t>(cloud_count);
  std::copy_n(cloud_points.begin(), m, to.cloud_points.begin());
  for (std::size_t i = 0; i < m; ++i) to.cloud_normals[i] = decode_normal(cloud_normals[i]);
  std::copy_n(cloud_pixels.begin(), m, to.cloud_pixels.begin());
  std::copy_n(cloud_curvature.begin(), m, to.cloud_curvature.begin());
  to.count = count;
  to.cloud_count = cloud_count;
  to.resolution_m = resolution_m;
  to.voxel_leaf_m = voxel_leaf_m;
  return true;
}

void StoredGeometry::assign(const StoredGeometry& from) {
  const auto n = static_cast<std::size_t>(std::min(from.count, capacity()));
  std::copy_n(from.points_cam.begin(), n, points_cam.begin());
  std::copy_n(from.normals.begin(), n, normals.begin());
  std::copy_n(from.sigma_m.begin(), n, sigma_m.begin());
  std::copy_n(from.codes.begin(), n * static_cast<std::size_t>(geometry::kShotSize), codes.begin());
  std::copy_n(from.scales.begin(), n, scales.begin());
  count = static_cast<int>(n);
  const auto m = static_cast<std::size_t>(std::min(from.cloud_count, cloud_capacity()));
  std::copy_n(from.cloud_points.begin(), m, cloud_points.begin());
  std::copy_n(from.cloud_normals.begin(), m, cloud_normals.begin());
  std::copy_n(from.cloud_pixels.begin(), m, cloud_pixels.begin());
  std::copy_n(from.cloud_curvature.begin(), m, cloud_curvature.begin());
  cloud_count = static_cast<int>(m);
  resolution_m = from.resolution_m;
  voxel_leaf_m = from.voxel_leaf_m;
}

float StoredGeometry::encode(const float* values, std::uint8_t* codes) {
  float largest = 0.0F;
  for (int d = 0; d < geometry::kShotSize; ++d) {
    if (std::isfinite(values[d])) largest = std::max(largest, values[d]);
  }
  if (!(largest > 0.0F) || !std::isfinite(largest / 255.0F)) {
    std::fill_n(codes, geometry::kShotSize, 0);
    return 0.0F;
  }
  // The smallest scale at least largest / 255 that 255 × scale gives back: decoding and encoding
  // again then finds the same scale, so a map saved, loaded and saved is the same file.
  float scale = largest / 255.0F;
  for (int step = 0; step < 64 && (scale * 255.0F < largest || (scale * 255.0F) / 255.0F != scale); ++step) {
    scale = std::nextafter(scale, std::numeric_limits<float>::infinity());
  }
  for (int d = 0; d < geometry::kShotSize; ++d) {
    const float value = values[d];
    codes[d] = value > 0.0F && std::isfinite(value)
                   ? static_cast<std::uint8_t>(std::min(255.0F, std::nearbyint(value / scale)))
                   : std::uint8_t{0};
  }
  return scale;
}

void StoredGeometry::decode(const std::uint8_t* codes, float scale, float* values) {
  for (int d = 0; d < geometry::kShotSize; ++d) values[d] = static_cast<float>(codes[d]) * scale;
}

std::array<std::int16_t, 3> StoredGeometry::encode_normal(const Eigen::Vector3f& normal) {
  std::array<std::int16_t, 3> codes{};
  for (int i = 0; i < 3; ++i) {
    const float component = normal[i];
    codes[static_cast<std::size_t>(i)] =
        std::isfinite(component) ? static_cast<std::int16_t>(std::nearbyint(std::clamp(component, -1.0F, 1.0F) * 32767.0F))
                                 : std::int16_t{0};
  }
  return codes;
}

Eigen::Vector3f StoredGeometry::decode_normal(const std::array<std::int16_t, 3>& codes) {
  return Eigen::Vector3f(static_cast<float>(codes[0]), static_cast<float>(codes[1]), static_cast<float>(codes[2])) /
         32767.0F;
}

double AdaptiveLoopThreshold::value() const {
  if (!adaptive_ || state_.count < 2) return initial_;
  const double n = state_.count;
  const double mean_p = state_.sum_p / n;
  const double mean_g = state_.sum_g / n;
  const double sigma_p = std::sqrt(std::max(0.0, state_.sum_sq_p / n - mean_p * mean_p));
  const double sigma_g = std::sqrt(std::max(0.0, state_.sum_sq_g / n - mean_g * mean_g));
  return (mean_p - deviations_ * sigma_p) + (mean_g - deviations_ * sigma_g);
}

void AdaptiveLoopThreshold::add(int photometric_inliers, int geometric_inliers) {
  ++state_.count;
  state_.sum_p += photometric_inliers;
  state_.sum_sq_p += static_cast<double>(photometric_inliers) * photometric_inliers;
  state_.sum_g += geometric_inliers;
  state_.sum_sq_g += static_cast<double>(geometric_inliers) * geometric_inliers;
}

}  // namespace rankslam::slam
