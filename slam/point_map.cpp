#include "rankslam/slam/point_map.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

namespace rankslam::slam {
namespace {

// 21 bits per axis: ±1 048 575 voxels, ±21 km at 2 cm.
std::int64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  constexpr std::int64_t kMask = (1LL << 21) - 1;
  return ((x & kMask) << 42) | ((y & kMask) << 21) | (z & kMask);
}

std::size_t hash(std::int64_t key) {
  auto h = static_cast<std::uint64_t>(key);
  h ^= h >> 33U;
  h *= 0xff51afd7ed558ccdULL;
  h ^= h >> 33U;
  return static_cast<std::size_t>(h);
}

}  // namespace

PointMap::PointMap(double voxel_m, std::size_t max_points)
    : inverse_voxel_m_(static_cast<float>(1.0 / voxel_m)),
      max_points_(std::min<std::size_t>(max_points, kNoVoxel)),
      // A load factor of at most two thirds keeps linear probing short.
      mask_(std::bit_ceil(max_points_ + max_points_ / 2) - 1),
      slots_(mask_ + 1, kNoVoxel),
      voxels_(max_points_) {}

void PointMap::clear() {
  std::fill(slots_.begin(), slots_.end(), kNoVoxel);
  used_ = 0;
  points_ = 0;
  rejected_ = 0;
}

std::int64_t PointMap::key_of(const Eigen::Vector3f& point_world) const {
  const Eigen::Vector3f scaled = point_world * inverse_voxel_m_;
  return pack(static_cast<std::int64_t>(std::floor(scaled.x())), static_cast<std::int64_t>(std::floor(scaled.y())),
              static_cast<std::int64_t>(std::floor(scaled.z())));
}

std::size_t PointMap::find_slot(std::int64_t key) const {
  std::size_t slot = hash(key) & mask_;
  while (slots_[slot] != kNoVoxel && voxels_[slots_[slot]].key() != key) slot = (slot + 1) & mask_;
  return slot;
}

bool PointMap::insert(const Eigen::Vector3f& point_world, std::uint8_t blue, std::uint8_t green, std::uint8_t red) {
  if (!point_world.allFinite()) return false;
  const std::int64_t key = key_of(point_world);
  const std::size_t slot = find_slot(key);
  const std::uint32_t index = slots_[slot];
  if (index == kNoVoxel) {
    if (used_ >= max_points_) {
      ++rejected_;
      return false;
    }
    Voxel& voxel = voxels_[used_];
    voxel.set_key(key);
    voxel.sum = point_world;
    voxel.blue_sum = blue;
    voxel.green_sum = green;
    voxel.red_sum = red;
    voxel.count = 1;
    slots_[slot] = static_cast<std::uint32_t>(used_++);
    ++points_;
    return true;
  }
  Voxel& voxel = voxels_[index];
  voxel.sum += point_world;
  voxel.blue_sum += blue;
  voxel.green_sum += green;
  voxel.red_sum += red;
  ++voxel.count;
  ++points_;
  return true;
}

bool PointMap::remove(const Eigen::Vector3f& point_world, std::uint8_t blue, std::uint8_t green, std::uint8_t red) {
  if (!point_world.allFinite()) return false;
  std::size_t slot = find_slot(key_of(point_world));
  const std::uint32_t index = slots_[slot];
  if (index == kNoVoxel) return false;
  Voxel& voxel = voxels_[index];
  --points_;
  if (voxel.count > 1) {
    voxel.sum -= point_world;
    voxel.blue_sum -= std::min<std::uint32_t>(blue, voxel.blue_sum);
    voxel.green_sum -= std::min<std::uint32_t>(green, voxel.green_sum);
    voxel.red_sum -= std::min<std::uint32_t>(red, voxel.red_sum);
    --voxel.count;
    return true;
  }
  // The last point: the last voxel moves into its room and the table forgets it. Linear probing
  // deletes by shifting back the entries after the hole that could have sat in it.
  const auto last = static_cast<std::uint32_t>(used_ - 1);
  if (index != last) {
    slots_[find_slot(voxels_[last].key())] = index;
    voxels_[index] = voxels_[last];
  }
  --used_;
  for (std::size_t next = (slot + 1) & mask_; slots_[next] != kNoVoxel; next = (next + 1) & mask_) {
    const std::size_t home = hash(voxels_[slots_[next]].key()) & mask_;
    // The entry at `next` may fill the hole unless its home lies cyclically in (slot, next].
    const bool home_after_hole = slot <= next ? (slot < home && home <= next) : (slot < home || home <= next);
    if (home_after_hole) continue;
    slots_[slot] = slots_[next];
    slot = next;
  }
  slots_[slot] = kNoVoxel;
  return true;
}

std::string PointMap::to_ply(const Eigen::Isometry3d& T_out_world) const {
  const Eigen::Isometry3f T = T_out_world.cast<float>();
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment rankslam map\nelement vertex " +
                       std::to_string(used_) +
                       "\nproperty float x\nproperty float y\nproperty float z\n"
                       "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  constexpr std::size_t kVertexBytes = 3 * sizeof(float) + 3;
  std::string ply = std::move(header);
  std::size_t offset = ply.size();
  ply.resize(offset + used_ * kVertexBytes);
  static_assert(std::endian::native == std::endian::little, "PLY output assumes a little-endian host");
  for (std::size_t i = 0; i < used_; ++i) {
    const Voxel& voxel = voxels_[i];
    const Eigen::Vector3f mean = T * Eigen::Vector3f(voxel.sum / static_cast<float>(voxel.count));
    std::memcpy(&ply[offset], mean.data(), 3 * sizeof(float));
    ply[offset + 12] = static_cast<char>(voxel.red_sum / voxel.count);
    ply[offset + 13] = static_cast<char>(voxel.green_sum / voxel.count);
    ply[offset + 14] = static_cast<char>(voxel.blue_sum / voxel.count);
    offset += kVertexBytes;
  }
  return ply;
}

}  // namespace rankslam::slam
