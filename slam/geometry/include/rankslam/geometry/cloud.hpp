#pragma once

// Cloud pre-processing from the organised depth image (docs/methods.md §3, thesis §4.4.1–
// 4.4.2): pass-through, adaptive voxel grid ρ = C·φ, and PCA normals over the dense cloud with a
// deliberately large support, oriented toward the camera.
//
// The depth image's organisation replaces the trees PCL would use:
//  - φ (mean nearest-neighbour distance) takes each pixel's nearest neighbour among its 8 image
//    neighbours, on every resolution_pixel_stride-th pixel;
//  - the voxel grid is one pass over the pixels into a fixed hash table (consecutive pixels
//    mostly fall into the same voxel, so most pixels skip the hash);
//  - the same pass sums the points of every 4 × 4 pixel block. A sampled point's dense
//    neighbours within the support radius R lie inside the pixel window that R spans at its
//    depth. The PCA takes each block of that window by its point count and mean: whole when its
//    bounding box lies inside the sphere of radius R, not at all when outside, and in between
//    with the share of its squared-distance range inside R (a soft boundary one block wide).
//    A block across a depth edge is split into a near and a far part (its pixels on either
//    side of its middle depth), each taken like a block, so that, unlike with integral images,
//    no surface behind an edge is mixed in. Against the noise-free geometry of simulated frames
//    these normals are as close as the dense radius-search PCA, which the sensor noise moving
//    points in and out of the hard radius disturbs more (test/unit/geometry, normals_test).

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "rankslam/geometry/config.hpp"
#include "rankslam/geometry/status.hpp"
#include "rankslam/parallel/thread_team.hpp"
#include "rankslam/camera/depth_camera.hpp"

namespace rankslam::geometry {

/// The sampled cloud of one frame: voxel centroids with their normals, camera frame.
struct SampledCloud {
  std::vector<Eigen::Vector3f> points;   ///< capacity entries; the first `size` are valid
  std::vector<Eigen::Vector3f> normals;  ///< unit, n·p < 0 (facing the camera)
  std::vector<Eigen::Vector2f> pixels;   ///< mean pixel (u, v) of each voxel's dense points
  /// Surface variation λ₀ / (λ₀ + λ₁ + λ₂) of the normal's PCA (Pauly et al. 2002): 0 on a plane,
  /// up to 1/3 for isotropic scatter.
  std::vector<float> curvature;
  std::vector<std::int32_t> dense_counts;  ///< dense points per voxel
  int size = 0;
  int dense_points = 0;       ///< valid pixels after the pass-through
  float resolution_m = 0.0F;  ///< φ: mean nearest-neighbour distance of the dense cloud
  float voxel_leaf_m = 0.0F;  ///< ρ actually used
  float normal_radius_m = 0.0F;
  int dropped_normals = 0;    ///< voxels dropped for too few dense neighbours

  [[nodiscard]] std::span<const Eigen::Vector3f> point_span() const {
    return {points.data(), static_cast<std::size_t>(size)};
  }
  [[nodiscard]] std::span<const Eigen::Vector3f> normal_span() const {
    return {normals.data(), static_cast<std::size_t>(size)};
  }
};

/// Mean camera-frame point of every kBlock × kBlock pixel block of the pass-through cloud,
/// structure-of-arrays with kPad empty blocks after every row, so that the normal estimation can
/// read 8 blocks at a time anywhere in a row.
struct BlockImage {
  static constexpr int kBlock = 4;
  static constexpr int kPad = 8;
  /// One layer of blocks: each block's points by their mean, count and axis-aligned bounds (as
  /// centre and half extent, the form the normals' sphere test takes).
  struct Layer {
    std::vector<float> x, y, z;  ///< mean point
    std::vector<float> weight;   ///< points; 0 for none
    std::vector<float> centre_x, centre_y, centre_z;
    std::vector<float> half_x, half_y, half_z;

    [[nodiscard]] Eigen::Vector3f mean(std::size_t b) const { return {x[b], y[b], z[b]}; }
    /// Set-up (allocates): `blocks` blocks, all empty.
    void reserve(std::size_t blocks);
  };
  int width = 0;   ///< blocks per row
  int height = 0;  ///< block rows
  int stride = 0;  ///< width + kPad
  /// Every block's points. A block across a depth edge, whose mean would float between two
  /// surfaces, is split at its points' middle depth into two parts, one surface each: here its
  /// near part.
  Layer front;
  /// The far part of each block across a depth edge; empty for every other block.
  Layer back;

  [[nodiscard]] std::size_t index(int u, int v) const {
    return static_cast<std::size_t>(v) * static_cast<std::size_t>(stride) + static_cast<std::size_t>(u);
  }
  [[nodiscard]] bool across_depth_edge(std::size_t b) const { return back.weight[b] > 0.0F; }

  /// Set-up (allocates): blocks for an image of the given pixel size.
  void reserve(int image_width, int image_height);
};

/// PCA normal of the dense points within radius_m of `center` (camera frame) in the pixel window
/// the radius spans around `pixel`, from the block means as described above (at most about
/// samples_per_axis blocks per axis: wider windows are strided), oriented toward the camera.
/// fx: focal length [px]. Returns the number of dense points used (weighted; the normal is
/// untouched below 3). Exposed for tests; CloudPreprocessor calls it for every voxel.
/// best_kernel: sum the window with the vector kernel (Highway: up to 8 blocks at a time, fused
/// multiply-adds) where parallel::vector_kernels_enabled() (false: the portable 4-block loop;
/// the two differ only by float rounding, the order of the sums and the fused multiply-adds, and
/// tests compare them).
int organised_normal(const BlockImage& blocks, float fx, const Eigen::Vector3f& center,
                     const Eigen::Vector2f& pixel, float radius_m, int samples_per_axis,
                     Eigen::Vector3f& normal, float* curvature = nullptr, bool best_kernel = true);

/// Mean nearest-neighbour distance of the pass-through cloud, estimated on every stride-th pixel
/// from its 8 image neighbours; 0 when no pixel has a valid neighbour. Allocates (tests, tools).
float organised_resolution(const cv::Mat& depth, const camera::DepthCameraModel& camera, int stride,
                           float min_depth_m, float max_depth_m);

/// Depth image → SampledCloud. configure() allocates; process() does not.
class CloudPreprocessor {
 public:
  /// Set-up: validates the config, sizes the hash table and the cloud for up to
  /// max_sampled_points voxels. Returns an error message, empty on success. With a team, the
  /// voxels' normals are shared among its threads.
  [[nodiscard]] std::string configure(const camera::DepthCameraModel& camera,
                                      const GeometryConfig& config, int max_sampled_points,
                                      parallel::ThreadTeam* team = nullptr);
  [[nodiscard]] bool configured() const { return max_points_ > 0; }
  [[nodiscard]] int capacity() const { return max_points_; }

  /// Makes a cloud with room for capacity() points (set-up).
  [[nodiscard]] SampledCloud make_cloud() const;

  /// The block means of the last process() call (for tests and tools).
  [[nodiscard]] const BlockImage& blocks() const { return blocks_; }

  /// Per frame: depth (CV_16UC1, camera size, raw units) → cloud. The cloud must come from
  /// make_cloud() of this preprocessor. When the voxel count exceeds the capacity the leaf
  /// grows by 25 % and the frame is voxelised again (a few times at most).
  GeometryStatus process(const cv::Mat& depth, SampledCloud& cloud);

 private:
  struct Slot {
    std::int32_t x = 0;
    std::int32_t y = 0;
    std::int32_t z = 0;
    std::int32_t voxel = -1;
    std::uint32_t generation = 0;
  };
  // Sums, bounds and point counts of the 4 × 4 pixel blocks, structure-of-arrays (`stride`
  // blocks a row, a multiple of 8) so that a row of pixels updates 8 blocks at a time. Bounds
  // start at ±infinity, so that blocks without points need no first-point case.
  struct BlockSums {
    int stride = 0;
    std::vector<float> sum_x, sum_y, sum_z;
    std::vector<float> min_x, min_y, min_z;
    std::vector<float> max_x, max_y, max_z;
    std::vector<std::int32_t> count;

    void reserve(int blocks_per_row, int block_rows);
    void clear();
    /// Adds one image row's points (z = 0: no point) to the blocks of its block row, each block's
    /// points in pixel order (a vector of blocks at a time where the CPU has a vector target).
    void add_row(const float* x, const float* y, const float* z, int width, int block_row);
  };
  struct Accumulator {
    float x = 0.0F;  // sums of ~10²–10³ points of ≤ 4 m: float keeps the centroid to < 1 µm
    float y = 0.0F;
    float z = 0.0F;
    float u = 0.0F;
    float v = 0.0F;
    std::int32_t count = 0;
  };
  // Direct-mapped cache of recently used voxels in front of the hash table: the voxels of the
  // last few rows fit in it (L1-resident), the table does not.
  static constexpr std::size_t kRecentSlots = 512;
  // The hash table's slots in use at the start of a band: a frame's few thousand voxels in
  // slots that stay in the core's cache. The table is sized for the capacity (twice
  // max_points_ slots), which spread a frame's voxels over more memory than the cache holds, so
  // that nearly every new voxel's slot was a cache miss. A band whose voxels fill half of the
  // slots in use doubles them.
  static constexpr std::size_t kFirstSlots = 4096;
  // The voxel grid of one band of image rows: its own hash table (its first mask + 1 slots in
  // use), voxels numbered in the order they first appear in the band, their sums and cells, and
  // one row's points and voxel coordinates (z = 0: no point), filled a row at a time (a vector
  // of pixels at a time) before the hashing pass.
  struct VoxelBand {
    std::uint32_t generation = 0;
    std::size_t mask = 0;
    std::vector<Slot> slots;
    std::vector<Slot> recent;
    std::vector<Accumulator> accumulators;
    std::vector<Eigen::Vector3i> cells;
    std::vector<float> row_x, row_y, row_z;
    std::vector<std::int32_t> row_cell_x, row_cell_y, row_cell_z;
    int voxels = 0;
    int dense_points = 0;
  };
  // The image is voxelised as kVoxelBands bands of rows, concurrently with a team, then the
  // bands are merged in row order, so the voxels keep the order of their first pixel in the
  // image whatever the team's size.
  static constexpr int kVoxelBands = 2;

  /// Splits depth-edge block `block` (block coordinates bu, bv) at split_z into its near part
  /// (blocks_.front) and far part (blocks_.back).
  void split_block(const cv::Mat& depth, int bu, int bv, float split_z, std::size_t block);
  /// organised_resolution() of the depth image with this preprocessor's settings, its rows on
  /// the team's threads (the same value).
  float resolution(const cv::Mat& depth);
  /// Fills band 0's accumulators with every voxel; false when more than max_points_ appear.
  bool voxelise(const cv::Mat& depth, float leaf_m, int& voxels, int& dense_points);
  /// Voxelises image rows [row_begin, row_end) into `band`; false when its voxels exceed
  /// max_points_.
  bool voxelise_rows(const cv::Mat& depth, float leaf_m, int row_begin, int row_end, VoxelBand& band);
  /// Voxel of `cell` in `band`, added (with empty sums) when new; −1 when the band is full.
  int find_or_add_voxel(VoxelBand& band, const Eigen::Vector3i& cell);
  /// Starts a new generation of `band`'s table and its recent cache (every slot free).
  static void next_generation(VoxelBand& band);
  /// Doubles the slots `band` uses and enters its voxels again.
  void grow_slots(VoxelBand& band);

  camera::DepthCameraModel camera_;
  GeometryConfig config_;
  int max_points_ = 0;
  std::size_t mask_ = 0;  // of the whole table
  std::array<VoxelBand, kVoxelBands> bands_;
  // Per voxel, before the voxels without a normal are dropped.
  std::vector<Eigen::Vector3f> voxel_normals_;
  std::vector<float> voxel_curvature_;
  std::vector<std::int32_t> voxel_normal_support_;
  std::vector<double> neighbour_distances_;  // per sampled pixel of the resolution estimate
  parallel::ThreadTeam* team_ = nullptr;
  BlockSums block_sums_;
  BlockImage blocks_;
  // Rays of the camera model as planes (the vectorised row pass loads 8 of each at a time).
  // Cloud stage per frame on fr1_rpy_head (perf_geometry): 7.1 → 6.8 ms; same voxels.
  std::vector<float> ray_x_, ray_y_;
};

}  // namespace rankslam::geometry
