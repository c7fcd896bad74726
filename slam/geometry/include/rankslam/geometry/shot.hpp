#pragma once

// SHOT — Signature of Histograms of OrienTations (Tombari, Salti & Di Stefano, ECCV 2010), the
// shape-only variant, computed as PCL's pcl::SHOTEstimation (1.13) does so that descriptors are
// interchangeable with it (docs/methods.md §5):
//  - local reference frame: eigenvectors of the covariance of the support points about the
//    keypoint, each weighted by (R − distance) (Tombari et al.'s SHOT LRF); x and z signs point
//    toward the majority of the support, ties broken on the 5 median-distance neighbours;
//    y = z × x;
//  - 32 spatial volumes: 8 azimuth × 2 elevation × 2 radial (at R/2) sectors of the LRF;
//  - per volume a histogram of cos(LRF z, neighbour normal) with 10 bins plus PCL's 11th slot
//    (cos = 1 rounds to bin 10), so 32 × 11 = 352 values;
//  - quadrilinear interpolation: each neighbour votes into its cosine bin and the adjacent one,
//    and into the adjacent radial, elevation and azimuth volumes by distance to their centres;
//  - L2 normalisation.
// Arc functions are polynomial (|error| ≤ 10⁻⁵ rad) instead of libm's acos/atan2.

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "rankslam/geometry/point_grid.hpp"

namespace rankslam::geometry {

inline constexpr int kShotCosineBins = 10;
inline constexpr int kShotVolumes = 32;
inline constexpr int kShotSize = kShotVolumes * (kShotCosineBins + 1);  // 352
static_assert(kShotSize == 352, "SHOT descriptors have 352 values");

/// Why a descriptor could not be computed.
enum class ShotResult : std::uint8_t {
  kOk,
  kTooFewNeighbours,  ///< Fewer support points than required (descriptor or LRF).
  kDegenerate,        ///< Non-finite LRF or an all-zero histogram.
};

class ShotEstimator {
 public:
  ShotEstimator() = default;
  explicit ShotEstimator(int max_support) { reserve(max_support); }

  /// Set-up (allocates): room for up to max_support support points per descriptor.
  void reserve(int max_support);

  /// True (the default) uses the vector kernel (Highway) for the per-neighbour geometry where
  /// the CPU has one; false always uses the portable loop (both give the same descriptors; tests
  /// compare them).
  void use_best_kernel(bool best) { best_kernel_ = best; }
  /// True when this CPU runs the vector kernel (parallel::vector_kernels_enabled()).
  [[nodiscard]] static bool has_vector_kernel();

  /// Per keypoint, no allocation: the SHOT of `center` over the support points (with unit
  /// normals) within radius_m, found through `grid` (built over `points`, any cell size; a cell
  /// near radius_m is fastest). Writes kShotSize values to `descriptor` and, when non-null, the
  /// LRF as rows x, y, z to `lrf`.
  ShotResult compute(const Eigen::Vector3f& center, std::span<const Eigen::Vector3f> points,
                     std::span<const Eigen::Vector3f> normals, const PointGrid& grid,
                     float radius_m, int min_neighbours, float* descriptor,
                     Eigen::Matrix3f* lrf = nullptr);

 private:
  bool local_reference_frame(float radius_m, Eigen::Matrix3f& rf);

  int capacity_ = 0;
  bool best_kernel_ = true;
  int count_ = 0;  // support points other than the keypoint itself (distance > 0)
  // The support as structure of arrays, padded to whole blocks of 8, so that the per-neighbour
  // geometry (LRF coordinates, arc functions, the bins and weights of the votes) runs 8
  // neighbours at a time (vector kernel, chosen at run time); only the additions into the histogram,
  // scattered by nature, stay one at a time. SHOT per frame on fr1_rpy_head (perf_geometry, about
  // 300 support points per keypoint): 7.4 ms with one neighbour at a time and branches, 4.0 ms
  // so, 3.3 ms with the LRF's sign votes as a plain loop (Eigen's boolean-array casts are scalar).
  std::vector<float> dx_, dy_, dz_, d2_;  // neighbour − keypoint, squared distance
  std::vector<float> nx_, ny_, nz_;       // neighbour normal
  std::vector<int> neighbours_;           // neighbour index into the points
  std::vector<float> distance_;
  // Per neighbour, filled block-wise before the votes: the bins and weights of its five votes
  // (own volume, adjacent cosine bin, radial shell, elevation and azimuth volume).
  std::vector<std::int32_t> own_, cosine_, radial_, elevation_, azimuth_;
  std::vector<float> own_weight_, cosine_weight_, radial_weight_, elevation_weight_, azimuth_weight_;
  std::vector<std::pair<float, int>> sorted_;  // tie-break scratch
};

}  // namespace rankslam::geometry
