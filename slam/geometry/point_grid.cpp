#include "rankslam/geometry/point_grid.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>

#include "vector_kernels.hpp"

namespace rankslam::geometry {

void PointGrid::reserve(int max_points) {
  capacity_ = std::max(0, max_points);
  std::size_t slots = 64;
  while (slots < 2 * static_cast<std::size_t>(capacity_)) slots *= 2;
  slots_.assign(slots, Slot{});
  mask_ = slots - 1;
  generation_ = 0;
  cell_list_.assign(static_cast<std::size_t>(capacity_), Cell{});
  point_cell_.assign(static_cast<std::size_t>(capacity_), -1);
  sorted_.assign(static_cast<std::size_t>(capacity_) + 8, 0);
  for (std::vector<float>* v : {&sorted_x_, &sorted_y_, &sorted_z_}) {
    v->assign(static_cast<std::size_t>(capacity_) + 8, 0.0F);
  }
  points_ = {};
  cell_count_ = 0;
}

std::int32_t PointGrid::cell_coordinate(float value) const {
  return floor_to_int(value * inverse_cell_);
}

std::size_t PointGrid::slot_of(std::int32_t x, std::int32_t y, std::int32_t z) const {
  return hash_cell(x, y, z) & mask_;
}

int PointGrid::find_cell(std::int32_t x, std::int32_t y, std::int32_t z) const {
  std::size_t s = slot_of(x, y, z);
  for (;;) {
    const Slot& slot = slots_[s];
    if (slot.generation != generation_) return -1;
    if (slot.x == x && slot.y == y && slot.z == z) return slot.cell;
    s = (s + 1) & mask_;
  }
}

bool PointGrid::build(std::span<const Eigen::Vector3f> points, float cell_m) {
  if (static_cast<int>(points.size()) > capacity_ || !(cell_m > 0.0F) || slots_.empty()) {
    points_ = {};
    cell_count_ = 0;
    return false;
  }
  points_ = points;
  cell_m_ = cell_m;
  inverse_cell_ = 1.0F / cell_m;
  // A new generation empties every slot without touching them; on wrap-around clear for real.
  if (++generation_ == 0) {
    for (Slot& slot : slots_) slot.generation = 0;
    generation_ = 1;
  }
  cell_count_ = 0;
  const int n = static_cast<int>(points.size());
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = points[static_cast<std::size_t>(i)];
    const std::int32_t x = cell_coordinate(p.x());
    const std::int32_t y = cell_coordinate(p.y());
    const std::int32_t z = cell_coordinate(p.z());
    std::size_t s = slot_of(x, y, z);
    int cell = -1;
    for (;;) {
      Slot& slot = slots_[s];
      if (slot.generation != generation_) {
        // At most n ≤ capacity cells in a table of ≥ 2·capacity slots: a free slot always exists.
        slot = Slot{x, y, z, cell_count_, generation_};
        cell_list_[static_cast<std::size_t>(cell_count_)] = Cell{x, y, z, 0, 0};
        cell = cell_count_++;
        break;
      }
      if (slot.x == x && slot.y == y && slot.z == z) {
        cell = slot.cell;
        break;
      }
      s = (s + 1) & mask_;
    }
    point_cell_[static_cast<std::size_t>(i)] = cell;
    ++cell_list_[static_cast<std::size_t>(cell)].count;
  }
  int start = 0;
  for (int c = 0; c < cell_count_; ++c) {
    Cell& cell = cell_list_[static_cast<std::size_t>(c)];
    cell.start = start;
    start += cell.count;
    cell.count = 0;  // refilled below as the write cursor
  }
  for (int i = 0; i < n; ++i) {
    Cell& cell = cell_list_[static_cast<std::size_t>(point_cell_[static_cast<std::size_t>(i)])];
    const auto k = static_cast<std::size_t>(cell.start + cell.count++);
    sorted_[k] = i;
    const Eigen::Vector3f& p = points[static_cast<std::size_t>(i)];
    sorted_x_[k] = p.x();
    sorted_y_[k] = p.y();
    sorted_z_[k] = p.z();
  }
  return true;
}

int PointGrid::gather_in_radius(const Eigen::Vector3f& q, float radius_m, const RadiusGather& out,
                                int& written) const {
  written = 0;
  int support = 0;
  const float r2 = radius_m * radius_m;
  const bool vector_runs = parallel::vector_kernels_enabled();
  for_each_cell_near(q, radius_m, [&](const Cell& cell) {
    const auto b = static_cast<std::size_t>(cell.start);
    if (vector_runs) {
      vector::gather_run(sorted_x_.data() + b, sorted_y_.data() + b, sorted_z_.data() + b, sorted_.data() + b, q,
                         r2, cell.count, out, written, support);
      return;
    }
    for (std::size_t j = b; j < b + static_cast<std::size_t>(cell.count); ++j) {
      const float dx = sorted_x_[j] - q.x();
      const float dy = sorted_y_[j] - q.y();
      const float dz = sorted_z_[j] - q.z();
      const float d2 = dx * dx + (dy * dy + dz * dz);
      if (!(d2 <= r2)) continue;
      ++support;
      if (d2 == 0.0F || written == out.capacity) continue;
      const auto k = static_cast<std::size_t>(written++);
      out.dx[k] = dx;
      out.dy[k] = dy;
      out.dz[k] = dz;
      out.d2[k] = d2;
      out.index[k] = sorted_[j];
    }
  });
  return support;
}

int PointGrid::within_radius(const Eigen::Vector3f& q, float r2, int begin, int count, int* indices,
                             float* squared_distances) const {
  const auto b = static_cast<std::size_t>(begin);
  int found = 0;
  int done = 0;
  if (parallel::vector_kernels_enabled()) {
    found = vector::within_radius(sorted_x_.data() + b, sorted_y_.data() + b, sorted_z_.data() + b,
                                  sorted_.data() + b, q, r2, count, indices, squared_distances, done);
  }
  for (int k = done; k < count; ++k) {
    const auto j = b + static_cast<std::size_t>(k);
    const float dx = sorted_x_[j] - q.x();
    const float dy = sorted_y_[j] - q.y();
    const float dz = sorted_z_[j] - q.z();
    const float d2 = dx * dx + (dy * dy + dz * dz);
    if (d2 <= r2) {
      indices[found] = sorted_[j];
      squared_distances[found] = d2;
      ++found;
    }
  }
  return found;
}

int PointGrid::nearest(const Eigen::Vector3f& q, int k, int exclude, int max_ring, int* indices,
                       float* squared_distances) const {
  k = std::clamp(k, 0, kMaxNeighbours);
  if (k == 0 || points_.empty()) return 0;
  const std::int32_t cx = cell_coordinate(q.x());
  const std::int32_t cy = cell_coordinate(q.y());
  const std::int32_t cz = cell_coordinate(q.z());
  int found = 0;
  const auto visit_cell = [&](std::int32_t x, std::int32_t y, std::int32_t z) {
    const int c = find_cell(x, y, z);
    if (c < 0) return;
    const Cell& cell = cell_list_[static_cast<std::size_t>(c)];
    for (int j = cell.start; j < cell.start + cell.count; ++j) {
      const int i = sorted_[static_cast<std::size_t>(j)];
      if (i == exclude) continue;
      keep_nearest((points_[static_cast<std::size_t>(i)] - q).squaredNorm(), i, k, found, indices,
            squared_distances);
    }
  };
  for (int ring = 0; ring <= max_ring; ++ring) {
    for (int dx = -ring; dx <= ring; ++dx) {
      for (int dy = -ring; dy <= ring; ++dy) {
        const bool face = std::abs(dx) == ring || std::abs(dy) == ring;
        for (int dz = -ring; dz <= ring; dz += (face ? 1 : 2 * std::max(ring, 1))) {
          visit_cell(cx + dx, cy + dy, cz + dz);
        }
      }
    }
    // Every point closer than the distance from q to the scanned block's boundary was seen.
    const Eigen::Vector3f lo =
        Eigen::Vector3f(static_cast<float>(cx - ring), static_cast<float>(cy - ring),
                        static_cast<float>(cz - ring)) * cell_m_;
    const Eigen::Vector3f hi =
        Eigen::Vector3f(static_cast<float>(cx + ring + 1), static_cast<float>(cy + ring + 1),
                        static_cast<float>(cz + ring + 1)) * cell_m_;
    const float margin = std::min((q - lo).minCoeff(), (hi - q).minCoeff());
    if (found == k && squared_distances[k - 1] <= margin * margin) break;
  }
  return found;
}

}  // namespace rankslam::geometry
