#pragma once

// The geometry front-end's SIMD kernels, written once with Highway for every vector unit (SSE4,
// AVX2, AVX-512, NEON) and dispatched at run time to the best one this CPU has. Callers use them
// where parallel::vector_kernels_enabled(), and their portable loops otherwise; each kernel says
// how its results compare with that loop's.

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

#include "rankslam/geometry/cloud.hpp"
#include "rankslam/geometry/point_grid.hpp"
#include "rankslam/geometry/shot.hpp"

#include "fast_math.hpp"

namespace rankslam::geometry::vector {

// --- Normals --------------------------------------------------------------------------------

/// The unstrided window of organised_normal, up to 8 blocks of a row at a time: the weighted
/// moments n, sx, sy, sz, sxx, sxy, sxz, syy, syz, szz of the blocks of both layers inside the
/// disc of `half_blocks` around block (bu, bv), relative to `center`, added to sums[]. The
/// portable 4-block loop's sums in another order and with fused multiply-adds (normals within
/// 0.1° of it, test/unit/geometry normals_test). The far parts of blocks across depth edges are
/// added where a group of blocks has any.
void window_moments(const BlockImage& blocks, const Eigen::Vector3f& center, int bu, int bv, int steps,
                    float half_blocks, float r2, float (&sums)[10]);

/// Row v of the window of organised_normal around block (bu, bv): the radius' pixel footprint
/// is a disc, so each row only as wide as the disc there (plus a block for the blocks' own
/// extent), clipped to the image: blocks [u_lo, u_hi].
inline void window_row(const BlockImage& blocks, int bu, int bv, float half_blocks, int v, int& u_lo, int& u_hi) {
  const float reach = half_blocks + 1.0F;
  const auto dv = static_cast<float>(v - bv);
  const int span = static_cast<int>(std::sqrt(std::max(0.0F, reach * reach - dv * dv)));
  u_lo = std::max(bu - span, 0);
  u_hi = std::min(bu + span, blocks.width - 1);
}

// --- SHOT votes -----------------------------------------------------------------------------

/// The votes' constants in float, as both the vector kernel and the portable loop use them.
struct VoteConstants {
  static constexpr auto kStride = static_cast<float>(kShotCosineBins + 1);  // values per volume
  static constexpr auto kBins = static_cast<float>(kShotCosineBins);
  static constexpr auto kVolumes = static_cast<float>(kShotVolumes);
  static constexpr auto kPi = static_cast<float>(detail::kPi);
  static constexpr auto kRad45 = static_cast<float>(0.78539816339744830961566084581988);
  static constexpr auto kRad90 = static_cast<float>(1.5707963267948966192313216916398);
  static constexpr auto kRad135 = static_cast<float>(2.3561944901923449288469825374596);
  static constexpr auto kRadPi78 = static_cast<float>(2.7488935718910690836548129603691);
  static constexpr float kInverseRad45 = 1.0F / kRad45;
  static constexpr float kInverseRad90 = 1.0F / kRad90;
};

/// Per neighbour: its offset from the keypoint and normal (inputs), and the bins (indices into
/// the descriptor) and weights of its five votes (outputs).
struct VoteArrays {
  const float* dx;
  const float* dy;
  const float* dz;
  const float* nx;
  const float* ny;
  const float* nz;
  const float* distance;
  std::int32_t* own;
  float* own_weight;
  std::int32_t* cosine;
  float* cosine_weight;
  std::int32_t* radial;
  float* radial_weight;
  std::int32_t* elevation;
  float* elevation_weight;
  std::int32_t* azimuth;
  float* azimuth_weight;
};

/// The local reference frame's axes and the radial shells' radii.
struct VoteFrame {
  Eigen::Vector3f x, y, z;
  float radius_1_4, radius_1_2, radius_3_4;
};

/// The bins and weights of neighbours [0, end) (end a multiple of 8, the arrays that long),
/// branch-free, as ShotEstimator's portable loop computes them: the same operations without
/// fused multiply-adds, so the same values bit for bit.
void shot_vote_bins(const VoteArrays& v, const VoteFrame& f, int end);

// --- Descriptor matching --------------------------------------------------------------------

/// The best so far of a block of A's rows (best_a, arg_a start at the block's first row) and of
/// every row of B over that block (arg_b holds indices into the whole of A).
struct Best {
  float* best_a;
  int* arg_a;
  float* best_b;
  int* arg_b;
  int row_offset;
};

/// Strictly greater keeps the lower index on ties, since rows and columns are visited ascending.
inline void update(Best& best, int i, int j, float s) {
  if (s > best.best_a[i]) {
    best.best_a[i] = s;
    best.arg_a[i] = j;
  }
  if (s > best.best_b[j]) {
    best.best_b[j] = s;
    best.arg_b[j] = i + best.row_offset;
  }
}

/// Every dot product of A's na rows with B's nb rows (dim floats each) into `best`, in 4 × 3
/// register blocks of fused multiply-adds. Each pair is summed as dot_in_lanes sums it, except a
/// row in a whole 4-row block against one of the last nb mod 3 columns: as dot_in_sequence.
void scan_dot_products(const float* a, int na, const float* b, int nb, int dim, Best& best);

/// One dot product summed as scan_dot_products sums it outside its blocks' last columns.
float dot_in_lanes(const float* x, const float* y, int dim);

/// Products from..dim−1 summed one at a time: a dot product as scan_dot_products sums its blocks'
/// last columns (from 0), and the tails past its vectors.
inline float dot_in_sequence(const float* x, const float* y, int dim, int from = 0) {
  float s = 0.0F;
  for (int k = from; k < dim; ++k) s += x[k] * y[k];
  return s;
}

// --- Binary descriptors ----------------------------------------------------------------------

/// Hamming distances of `n_source` 256-bit descriptors (4 words each, row after row) to the
/// targets [0, end), whose words are four planes of `stride` (plane k holds word k of every
/// target). Per source i: row_best[i] / row_arg[i] its nearest target over the targets covered,
/// the lowest index on ties. Per target j: col_best[j] / col_arg[j] replaced where a source is
/// strictly nearer (sources ascending: the lowest index on ties). Integer distances, so the
/// portable loop's values; returns the targets covered (whole vectors from 0, none on a target
/// without vectors).
int hamming_scan(const std::uint64_t* source, int n_source, const std::uint64_t* planes, int stride, int end,
                 std::int64_t* row_best, std::int64_t* row_arg, std::int64_t* col_best, std::int64_t* col_arg);

// --- Cloud pre-processing -------------------------------------------------------------------

/// One image row of the voxel grid's pass: every pixel's camera-frame point and voxel
/// coordinates, z = 0 (and voxel 0) where the pixel is empty or outside [min_m, max_m].
struct RowPoints {
  float* x;
  float* y;
  float* z;
  std::int32_t* cell_x;
  std::int32_t* cell_y;
  std::int32_t* cell_z;
};

/// The row's whole vectors of pixels from 0 on, as the portable loop computes them (the same
/// products and the floor of the same values); returns how many pixels it did.
int prepare_row(const std::uint16_t* raw, const float* ray_x, const float* ray_y, int width,
                float metres_per_unit, float min_m, float max_m, float inverse_leaf, const RowPoints& out);

/// One row's points (z = 0: none) added into the sums, bounds and counts of whole groups of
/// blocks of BlockImage::kBlock pixels, `blocks` of them from the row's start: each block's
/// points in pixel order, an absent point adding +0 and bounding as ±infinity, so the portable
/// loop's values. Returns the blocks done (a multiple of the vector's lanes).
int add_block_rows(const float* x, const float* y, const float* z, int blocks, float* sum_x, float* sum_y,
                   float* sum_z, float* min_x, float* min_y, float* min_z, float* max_x, float* max_y,
                   float* max_z, std::int32_t* count);

// --- Point grid -----------------------------------------------------------------------------

/// PointGrid::within_radius over whole vectors of a run of sorted points: the offsets' squared
/// distances x² + (y² + z²) without fused multiply-adds, so the portable loop's values. Returns
/// the hits (indices and squared distances, in order); `done` is how many points it covered.
int within_radius(const float* xs, const float* ys, const float* zs, const int* indices, const Eigen::Vector3f& q,
                  float r2, int count, int* hits, float* hit_d2, int& done);

/// One cell's run of PointGrid::gather_in_radius: the points within r2 other than q itself
/// appended to `out` from `written` on (at most out.capacity, each store a whole vector, so out's
/// arrays have 8 values of room past it; the run's arrays are read up to 7 values past `count`),
/// `support` raised by every point within r2. The portable loop's values, in its order.
void gather_run(const float* xs, const float* ys, const float* zs, const int* indices, const Eigen::Vector3f& q,
                float r2, int count, const PointGrid::RadiusGather& out, int& written, int& support);

}  // namespace rankslam::geometry::vector
