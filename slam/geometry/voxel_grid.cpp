#include "rankslam/geometry/cloud.hpp"

#include "rankslam/geometry/point_grid.hpp"
#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "vector_kernels.hpp"

// The voxel grid of the cloud pre-processing: each band of image rows hashes its pixels' voxels
// and sums their points (CloudPreprocessor::voxelise).
namespace rankslam::geometry {

namespace {

// ⌊v⌋ without branches for the per-pixel loop, exact for |v| < 2^20: a pass-through point
// (≤ 20 m, ray slope < 10) over a leaf ≥ 1 mm stays far inside that.
inline std::int32_t fast_floor(float v) {
  constexpr double kOffset = 1048576.0;
  return static_cast<std::int32_t>(static_cast<double>(v) + kOffset) - 1048576;
}

using vector::RowPoints;

void prepare_row_portable(const std::uint16_t* raw, const float* ray_x, const float* ray_y, int width,
                          float metres_per_unit, float min_m, float max_m, float inverse_leaf,
                          const RowPoints& out, int from = 0) {
  for (int u = from; u < width; ++u) {
    const float z = static_cast<float>(raw[u]) * metres_per_unit;
    const bool valid = raw[u] != 0 && z >= min_m && z <= max_m;
    const float x = ray_x[u] * z;
    const float y = ray_y[u] * z;
    out.x[u] = x;
    out.y[u] = y;
    out.z[u] = valid ? z : 0.0F;
    out.cell_x[u] = valid ? fast_floor(x * inverse_leaf) : 0;
    out.cell_y[u] = valid ? fast_floor(y * inverse_leaf) : 0;
    out.cell_z[u] = valid ? fast_floor(z * inverse_leaf) : 0;
  }
}



}  // namespace

bool CloudPreprocessor::voxelise(const cv::Mat& depth, float leaf_m, int& voxels,
                                 int& dense_points) {
  voxels = 0;
  dense_points = 0;
  block_sums_.clear();
  // Bands end on block rows, so that each block's sums come from one band.
  constexpr int kBlock = BlockImage::kBlock;
  const int block_rows = (depth.rows + kBlock - 1) / kBlock;
  std::array<int, kVoxelBands + 1> first_row{};
  for (int b = 0; b <= kVoxelBands; ++b) {
    first_row[static_cast<std::size_t>(b)] = std::min(depth.rows, block_rows * b / kVoxelBands * kBlock);
  }
  std::array<bool, kVoxelBands> fitted{};
  const auto voxelise_band = [&](int b, int /*thread*/) {
    const auto i = static_cast<std::size_t>(b);
    fitted[i] = voxelise_rows(depth, leaf_m, first_row[i], first_row[i + 1], bands_[i]);
  };
  parallel::for_each(team_, kVoxelBands, voxelise_band);
  VoxelBand& merged = bands_[0];
  if (!fitted[0]) return false;
  for (std::size_t b = 1; b < bands_.size(); ++b) {
    if (!fitted[b]) return false;
    const VoxelBand& band = bands_[b];
    for (int v = 0; v < band.voxels; ++v) {
      const int voxel = find_or_add_voxel(merged, band.cells[static_cast<std::size_t>(v)]);
      if (voxel < 0) return false;
      Accumulator& into = merged.accumulators[static_cast<std::size_t>(voxel)];
      const Accumulator& from = band.accumulators[static_cast<std::size_t>(v)];
      into.x += from.x;
      into.y += from.y;
      into.z += from.z;
      into.u += from.u;
      into.v += from.v;
      into.count += from.count;
    }
    merged.dense_points += band.dense_points;
  }
  voxels = merged.voxels;
  dense_points = merged.dense_points;
  return true;
}

int CloudPreprocessor::find_or_add_voxel(VoxelBand& band, const Eigen::Vector3i& cell) {
  std::size_t s = hash_cell(cell.x(), cell.y(), cell.z()) & band.mask;
  for (;;) {
    Slot& slot = band.slots[s];
    if (slot.generation != band.generation) {
      if (band.voxels == max_points_) return -1;
      const int voxel = band.voxels++;
      slot = Slot{cell.x(), cell.y(), cell.z(), voxel, band.generation};
      band.accumulators[static_cast<std::size_t>(voxel)] = Accumulator{};
      band.cells[static_cast<std::size_t>(voxel)] = cell;
      if (2 * static_cast<std::size_t>(band.voxels) > band.mask + 1 && band.mask < mask_) grow_slots(band);
      return voxel;
    }
    if (slot.x == cell.x() && slot.y == cell.y() && slot.z == cell.z()) return slot.voxel;
    s = (s + 1) & band.mask;
  }
}

void CloudPreprocessor::next_generation(VoxelBand& band) {
  if (++band.generation == 0) {
    for (Slot& slot : band.slots) slot.generation = 0;
    for (Slot& slot : band.recent) slot.generation = 0;
    band.generation = 1;
  }
}

void CloudPreprocessor::grow_slots(VoxelBand& band) {
  band.mask = 2 * band.mask + 1;
  next_generation(band);
  for (int voxel = 0; voxel < band.voxels; ++voxel) {
    const Eigen::Vector3i& cell = band.cells[static_cast<std::size_t>(voxel)];
    std::size_t s = hash_cell(cell.x(), cell.y(), cell.z()) & band.mask;
    while (band.slots[s].generation == band.generation) s = (s + 1) & band.mask;
    band.slots[s] = Slot{cell.x(), cell.y(), cell.z(), voxel, band.generation};
  }
}

bool CloudPreprocessor::voxelise_rows(const cv::Mat& depth, float leaf_m, int row_begin,
                                      int row_end, VoxelBand& band) {
  next_generation(band);
  band.mask = std::min(kFirstSlots - 1, mask_);
  band.voxels = 0;
  band.dense_points = 0;
  const float inverse_leaf = 1.0F / leaf_m;
  const float metres_per_unit = camera_.metres(1);
  const auto min_m = static_cast<float>(config_.min_depth_m);
  const auto max_m = static_cast<float>(config_.max_depth_m);
  const bool vector_rows = parallel::vector_kernels_enabled();
  const RowPoints row_points{band.row_x.data(), band.row_y.data(), band.row_z.data(),
                             band.row_cell_x.data(), band.row_cell_y.data(), band.row_cell_z.data()};
  for (int v = row_begin; v < row_end; ++v) {
    const std::uint16_t* row = depth.ptr<std::uint16_t>(v);
    // The points and voxel coordinates of the row first (vectorised where the CPU allows),
    // then the hashing and sums, which depend on the previous pixel's voxel.
    const std::size_t row_start = static_cast<std::size_t>(v) * static_cast<std::size_t>(depth.cols);
    const int done = vector_rows ? vector::prepare_row(row, ray_x_.data() + row_start, ray_y_.data() + row_start,
                                                       depth.cols, metres_per_unit, min_m, max_m, inverse_leaf,
                                                       row_points)
                                 : 0;
    prepare_row_portable(row, ray_x_.data() + row_start, ray_y_.data() + row_start, depth.cols, metres_per_unit,
                         min_m, max_m, inverse_leaf, row_points, done);
    block_sums_.add_row(band.row_x.data(), band.row_y.data(), band.row_z.data(), depth.cols,
                        v / BlockImage::kBlock);
    // Runs of valid pixels in one voxel, each summed on its own and then added to the voxel:
    // a run's additions depend on each other, but not on the next run's, so the core overlaps
    // them (summed pixel by pixel into the voxel, every addition waited for the last one). The
    // column sum of a run is exact: whole numbers below 2^24.
    const float* const xs = band.row_x.data();
    const float* const ys = band.row_y.data();
    const float* const zs = band.row_z.data();
    const std::int32_t* const cell_xs = band.row_cell_x.data();
    const std::int32_t* const cell_ys = band.row_cell_y.data();
    const std::int32_t* const cell_zs = band.row_cell_z.data();
    const auto row_v = static_cast<float>(v);
    const int columns = depth.cols;
    int points_in_row = 0;
    int u = 0;
    while (u < columns) {
      if (!(zs[u] > 0.0F)) {
        ++u;
        continue;
      }
      const std::int32_t x = cell_xs[u];
      const std::int32_t y = cell_ys[u];
      const std::int32_t zc = cell_zs[u];
      const int first = u;
      for (++u; u < columns && zs[u] > 0.0F && cell_xs[u] == x && cell_ys[u] == y && cell_zs[u] == zc; ++u) {
      }
      float sum_x = 0.0F;
      float sum_y = 0.0F;
      float sum_z = 0.0F;
      for (int k = first; k < u; ++k) {
        sum_x += xs[k];
        sum_y += ys[k];
        sum_z += zs[k];
      }
      int voxel = -1;
      Slot& recent = band.recent[hash_cell(x, y, zc) & (kRecentSlots - 1)];
      if (recent.generation == band.generation && recent.x == x && recent.y == y && recent.z == zc) {
        voxel = recent.voxel;
      } else {
        voxel = find_or_add_voxel(band, Eigen::Vector3i(x, y, zc));
        if (voxel < 0) return false;
        // After find_or_add_voxel: a table that grew started a new generation.
        recent = Slot{x, y, zc, voxel, band.generation};
      }
      const int length = u - first;
      Accumulator& sums = band.accumulators[static_cast<std::size_t>(voxel)];
      sums.x += sum_x;
      sums.y += sum_y;
      sums.z += sum_z;
      sums.u += static_cast<float>((first + u - 1) * length / 2);
      sums.v += row_v * static_cast<float>(length);
      sums.count += length;
      points_in_row += length;
    }
    band.dense_points += points_in_row;
  }
  return true;
}

}  // namespace rankslam::geometry
