#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace rankslam::slam {

/// Coloured point cloud merged on a voxel grid, with a capacity fixed at construction: points
/// falling in an occupied voxel refine its mean; points that would need a new voxel once the
/// map is full are counted and dropped, so memory never grows after set-up. A point can be taken
/// out again (the key-frame that added it retired); a voxel left empty frees its room.
class PointMap {
 public:
  PointMap(double voxel_m, std::size_t max_points);

  /// Adds a world-frame point with its BGR colour. False where the map was full (the point is
  /// counted as rejected) or the point is not finite.
  bool insert(const Eigen::Vector3f& point_world, std::uint8_t blue, std::uint8_t green, std::uint8_t red);
  /// Takes out a point insert() took, given as it was inserted. False (nothing changed) where no
  /// voxel holds its position.
  bool remove(const Eigen::Vector3f& point_world, std::uint8_t blue, std::uint8_t green, std::uint8_t red);
  void clear();

  [[nodiscard]] std::size_t size() const { return used_; }
  /// Points merged into the voxels (taken ones less those taken out).
  [[nodiscard]] std::uint64_t points() const { return points_; }
  [[nodiscard]] std::size_t capacity() const { return max_points_; }
  [[nodiscard]] std::uint64_t rejected_points() const { return rejected_; }

  /// The map as a binary little-endian PLY (x y z float, red green blue uchar), its points taken
  /// into the output frame by T_out_world.
  [[nodiscard]] std::string to_ply(const Eigen::Isometry3d& T_out_world = Eigen::Isometry3d::Identity()) const;

 private:
  // 36 bytes: the key in two halves keeps the struct at 4-byte alignment.
  struct Voxel {
    std::uint32_t key_low = 0;
    std::uint32_t key_high = 0;
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    std::uint32_t blue_sum = 0;
    std::uint32_t green_sum = 0;
    std::uint32_t red_sum = 0;
    std::uint32_t count = 0;

    [[nodiscard]] std::int64_t key() const {
      return static_cast<std::int64_t>((static_cast<std::uint64_t>(key_high) << 32U) | key_low);
    }
    void set_key(std::int64_t key) {
      key_low = static_cast<std::uint32_t>(static_cast<std::uint64_t>(key));
      key_high = static_cast<std::uint32_t>(static_cast<std::uint64_t>(key) >> 32U);
    }
  };
  static_assert(sizeof(Voxel) == 36);
  static constexpr std::uint32_t kNoVoxel = UINT32_MAX;

  [[nodiscard]] std::int64_t key_of(const Eigen::Vector3f& point_world) const;
  /// The table slot holding `key`'s voxel index, or of the free slot where it would go.
  [[nodiscard]] std::size_t find_slot(std::int64_t key) const;

  float inverse_voxel_m_;
  std::size_t max_points_;
  std::size_t mask_;
  /// Open-addressing hash table of indices into voxels_ (kNoVoxel: free), at most two thirds
  /// full: a table of indices, not of voxels, keeps the empty room at 4 bytes a slot.
  std::vector<std::uint32_t> slots_;
  /// The voxels in the order they were taken, max_points_ of them allocated at set-up.
  std::vector<Voxel> voxels_;
  std::size_t used_ = 0;
  std::uint64_t points_ = 0;
  std::uint64_t rejected_ = 0;
};

}  // namespace rankslam::slam
