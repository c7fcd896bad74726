#pragma once

// A hashed uniform grid over a small point set (the few thousand sampled points of a frame):
// fixed-radius and k-nearest queries without a tree. With the cell edge near the query scale a
// query touches 27 cells and a few dozen points, which beats a k-d tree's descent for the
// sampled cloud's sizes, and the build is linear (no sort).

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

namespace rankslam::geometry {

class PointGrid {
 public:
  /// One non-empty cell: integer coordinates and its run in sorted_indices().
  struct Cell {
    std::int32_t x = 0;
    std::int32_t y = 0;
    std::int32_t z = 0;
    std::int32_t start = 0;
    std::int32_t count = 0;
  };

  PointGrid() = default;
  explicit PointGrid(int max_points) { reserve(max_points); }

  /// Set-up (allocates): room for grids over up to max_points points.
  void reserve(int max_points);
  [[nodiscard]] int capacity() const { return capacity_; }

  /// Per frame, no allocation: bins points (kept by pointer; they must outlive the queries) into
  /// cells of edge cell_m, cell (⌊x/c⌋, ⌊y/c⌋, ⌊z/c⌋). False when points.size() > capacity() or
  /// cell_m is not positive.
  [[nodiscard]] bool build(std::span<const Eigen::Vector3f> points, float cell_m);

  [[nodiscard]] float cell_m() const { return cell_m_; }
  [[nodiscard]] int size() const { return static_cast<int>(points_.size()); }
  [[nodiscard]] std::span<const Cell> cells() const {
    return {cell_list_.data(), static_cast<std::size_t>(cell_count_)};
  }
  /// Point indices grouped by cell; cell c owns [c.start, c.start + c.count).
  [[nodiscard]] std::span<const int> sorted_indices() const {
    return {sorted_.data(), points_.size()};
  }
  /// Index into cells() of the cell holding (x, y, z), or −1 when it is empty.
  [[nodiscard]] int find_cell(std::int32_t x, std::int32_t y, std::int32_t z) const;
  [[nodiscard]] std::int32_t cell_coordinate(float value) const;

  /// Calls visit(index, squared_distance) for every point within radius_m of q (inclusive), cell
  /// by cell (x, y, z ascending) and in sorted_indices() order within a cell. The distance is
  /// (p − q).squaredNorm().
  template <class Visit>
  void for_each_in_radius(const Eigen::Vector3f& q, float radius_m, Visit&& visit) const {
    const float r2 = radius_m * radius_m;
    std::array<int, kRadiusChunk> hits{};
    std::array<float, kRadiusChunk> hit_d2{};
    for_each_cell_near(q, radius_m, [&](const Cell& cell) {
      const int end = cell.start + cell.count;
      for (int begin = cell.start; begin < end; begin += kRadiusChunk) {
        const int found = within_radius(q, r2, begin, std::min(kRadiusChunk, end - begin),
                                        hits.data(), hit_d2.data());
        for (int h = 0; h < found; ++h) {
          visit(hits[static_cast<std::size_t>(h)], hit_d2[static_cast<std::size_t>(h)]);
        }
      }
    });
  }

  /// Where gather_in_radius writes: per point its offset p − q, squared distance and index.
  /// Each array needs room for capacity + 8 values (points go out in blocks of up to 8).
  struct RadiusGather {
    float* dx;
    float* dy;
    float* dz;
    float* d2;
    int* index;
    int capacity;
  };
  /// The points of for_each_in_radius (the same points, order and squared distances), written
  /// side by side instead of visited one at a time: up to out.capacity of them, points at q
  /// itself (squared distance 0) left out. Returns how many points lie within the radius, q's own
  /// included; `written` says how many were written.
  int gather_in_radius(const Eigen::Vector3f& q, float radius_m, const RadiusGather& out,
                       int& written) const;

  /// Exact k nearest neighbours of q (excluding the point with index `exclude`, −1 for none),
  /// searched in growing shells of cells up to max_ring cells from q's cell; beyond that the
  /// result holds the nearest points found so far. Writes up to k indices and squared distances,
  /// nearest first, and returns how many. k ≤ kMaxNeighbours.
  static constexpr int kMaxNeighbours = 64;
  int nearest(const Eigen::Vector3f& q, int k, int exclude, int max_ring, int* indices,
              float* squared_distances) const;

 private:
  struct Slot {
    std::int32_t x = 0;
    std::int32_t y = 0;
    std::int32_t z = 0;
    std::int32_t cell = -1;  // index into cell_list_
    std::uint32_t generation = 0;
  };
  [[nodiscard]] std::size_t slot_of(std::int32_t x, std::int32_t y, std::int32_t z) const;
  /// Calls visit_cell(cell) for every non-empty cell of the box around q ± radius_m, x, y, z
  /// ascending.
  template <class VisitCell>
  void for_each_cell_near(const Eigen::Vector3f& q, float radius_m, VisitCell&& visit_cell) const {
    const std::int32_t x0 = cell_coordinate(q.x() - radius_m);
    const std::int32_t x1 = cell_coordinate(q.x() + radius_m);
    const std::int32_t y0 = cell_coordinate(q.y() - radius_m);
    const std::int32_t y1 = cell_coordinate(q.y() + radius_m);
    const std::int32_t z0 = cell_coordinate(q.z() - radius_m);
    const std::int32_t z1 = cell_coordinate(q.z() + radius_m);
    for (std::int32_t x = x0; x <= x1; ++x) {
      for (std::int32_t y = y0; y <= y1; ++y) {
        for (std::int32_t z = z0; z <= z1; ++z) {
          const int c = find_cell(x, y, z);
          if (c >= 0) visit_cell(cell_list_[static_cast<std::size_t>(c)]);
        }
      }
    }
  }
  /// The points at sorted positions [begin, begin + count) within r2 of q (squared distance
  /// ≤ r2), in order: their indices and squared distances into the outputs; returns how many.
  /// From the coordinates kept in sorted order, a vector at a time where the CPU has a vector target.
  int within_radius(const Eigen::Vector3f& q, float r2, int begin, int count, int* indices,
                    float* squared_distances) const;
  static constexpr int kRadiusChunk = 64;

  int capacity_ = 0;
  std::span<const Eigen::Vector3f> points_;
  float cell_m_ = 1.0F;
  float inverse_cell_ = 1.0F;
  std::uint32_t generation_ = 0;
  std::size_t mask_ = 0;
  std::vector<Slot> slots_;
  std::vector<Cell> cell_list_;
  int cell_count_ = 0;
  std::vector<int> point_cell_;
  std::vector<int> sorted_;
  // The points' coordinates in sorted_ order (8 padding entries at the end), so that a cell's
  // points are read side by side.
  std::vector<float> sorted_x_, sorted_y_, sorted_z_;
};

/// Keeps the k smallest (squared distance, index) pairs seen so far, ascending, by insertion;
/// `found` counts the kept pairs.
inline void keep_nearest(float d2, int index, int k, int& found, int* indices, float* distances) {
  if (found == k && d2 >= distances[k - 1]) return;
  int pos = found < k ? found++ : k - 1;
  while (pos > 0 && distances[pos - 1] > d2) {
    distances[pos] = distances[pos - 1];
    indices[pos] = indices[pos - 1];
    --pos;
  }
  distances[pos] = d2;
  indices[pos] = index;
}

/// Hash of integer cell coordinates (Teschner et al. 2003).
[[nodiscard]] inline std::uint32_t hash_cell(std::int32_t x, std::int32_t y, std::int32_t z) {
  return (static_cast<std::uint32_t>(x) * 73856093U) ^ (static_cast<std::uint32_t>(y) * 19349663U) ^
         (static_cast<std::uint32_t>(z) * 83492791U);
}

/// ⌊v⌋ as an integer, clamped to ±2^30 so that absurd coordinates cannot overflow.
[[nodiscard]] inline std::int32_t floor_to_int(float v) {
  constexpr float kLimit = 1073741824.0F;
  if (!(v > -kLimit)) return -1073741824;
  if (!(v < kLimit)) return 1073741824;
  const auto i = static_cast<std::int32_t>(v);
  return i - static_cast<std::int32_t>(v < static_cast<float>(i));
}

}  // namespace rankslam::geometry
