#include "rankslam/geometry/cloud.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "rankslam/geometry/point_grid.hpp"
#include "vector_kernels.hpp"

namespace rankslam::geometry {

namespace {

// Voxelisation retries with a 25 % larger leaf when the voxels exceed the capacity.
constexpr int kVoxelAttempts = 6;
constexpr float kLeafGrowth = 1.25F;


struct DepthRange {
  float min_m;
  float max_m;
  float metres_per_unit;
};

// Camera-frame point of pixel (u, v) if its depth is valid and inside the pass-through.
inline bool point_at(const cv::Mat& depth, const camera::DepthCameraModel& camera,
                     const DepthRange& range, int u, int v, Eigen::Vector3f& p) {
  const std::uint16_t raw = depth.ptr<std::uint16_t>(v)[u];
  if (raw == 0) return false;
  const float z = static_cast<float>(raw) * range.metres_per_unit;
  if (z < range.min_m || z > range.max_m) return false;
  p = camera.back_project(u, v, z);
  return true;
}

}  // namespace

namespace {

// The distance from each sampled pixel of row v (every stride-th from u = 1) to its nearest
// valid 8-neighbour in 3D, NaN where the pixel or all its neighbours are invalid.
void nearest_neighbour_distances(const cv::Mat& depth, const camera::DepthCameraModel& camera,
                                 const DepthRange& range, int v, int stride, double* out) {
  int k = 0;
  for (int u = 1; u + 1 < depth.cols; u += stride, ++k) {
    out[k] = std::numeric_limits<double>::quiet_NaN();
    Eigen::Vector3f p;
    if (!point_at(depth, camera, range, u, v, p)) continue;
    float best = std::numeric_limits<float>::infinity();
    for (int dv = -1; dv <= 1; ++dv) {
      for (int du = -1; du <= 1; ++du) {
        if (du == 0 && dv == 0) continue;
        Eigen::Vector3f q;
        if (!point_at(depth, camera, range, u + du, v + dv, q)) continue;
        best = std::min(best, (q - p).squaredNorm());
      }
    }
    if (std::isfinite(best)) out[k] = std::sqrt(static_cast<double>(best));
  }
}

int sampled_rows(int rows, int stride) { return rows > 2 ? (rows - 2 + stride - 1) / stride : 0; }
int sampled_columns(int cols, int stride) { return cols > 2 ? (cols - 2 + stride - 1) / stride : 0; }

// The mean of the finite distances, summed in image order.
float mean_of_finite(const double* distances, std::size_t count) {
  double sum = 0.0;
  long finite = 0;
  for (std::size_t i = 0; i < count; ++i) {
    if (std::isnan(distances[i])) continue;
    sum += distances[i];
    ++finite;
  }
  return finite > 0 ? static_cast<float>(sum / static_cast<double>(finite)) : 0.0F;
}

}  // namespace

float organised_resolution(const cv::Mat& depth, const camera::DepthCameraModel& camera, int stride,
                           float min_depth_m, float max_depth_m) {
  const DepthRange range{min_depth_m, max_depth_m, camera.metres(1)};
  stride = std::max(1, stride);
  const int rows = sampled_rows(depth.rows, stride);
  const int columns = sampled_columns(depth.cols, stride);
  std::vector<double> distances(static_cast<std::size_t>(rows) * static_cast<std::size_t>(columns));
  for (int r = 0; r < rows; ++r) {
    nearest_neighbour_distances(depth, camera, range, 1 + r * stride, stride,
                                distances.data() + static_cast<std::ptrdiff_t>(r) * columns);
  }
  return mean_of_finite(distances.data(), distances.size());
}

float CloudPreprocessor::resolution(const cv::Mat& depth) {
  const DepthRange range{static_cast<float>(config_.min_depth_m), static_cast<float>(config_.max_depth_m),
                         camera_.metres(1)};
  const int stride = std::max(1, config_.resolution_pixel_stride);
  const int rows = sampled_rows(depth.rows, stride);
  const int columns = sampled_columns(depth.cols, stride);
  const auto rows_of_distances = [&](int first, int end, int /*thread*/) {
    for (int r = first; r < end; ++r) {
      nearest_neighbour_distances(depth, camera_, range, 1 + r * stride, stride,
                                  neighbour_distances_.data() + static_cast<std::ptrdiff_t>(r) * columns);
    }
  };
  constexpr int kRowsPerChunk = 8;
  parallel::for_chunks(team_, rows, kRowsPerChunk, rows_of_distances);
  return mean_of_finite(neighbour_distances_.data(), static_cast<std::size_t>(rows) * static_cast<std::size_t>(columns));
}

std::string CloudPreprocessor::configure(const camera::DepthCameraModel& camera,
                                         const GeometryConfig& config, int max_sampled_points,
                                         parallel::ThreadTeam* team) {
  max_points_ = 0;
  team_ = team;
  if (const std::string_view bad = config.validate(); !bad.empty()) {
    return "geometry config: " + std::string(bad) + " is out of range";
  }
  if (camera.width() < 3 || camera.height() < 3) {
    return "geometry: depth camera model has no image size (" + std::to_string(camera.width()) +
           "x" + std::to_string(camera.height()) + ")";
  }
  if (max_sampled_points < 3 || max_sampled_points > 10'000'000) {
    return "geometry: max_sampled_points " + std::to_string(max_sampled_points) +
           " is out of range [3, 10000000]";
  }
  camera_ = camera;
  config_ = config;
  std::size_t slots = 64;
  while (slots < 2 * static_cast<std::size_t>(max_sampled_points)) slots *= 2;
  mask_ = slots - 1;
  const auto width = static_cast<std::size_t>(camera.width());
  for (VoxelBand& band : bands_) {
    band.generation = 0;
    band.slots.assign(slots, Slot{});
    band.recent.assign(kRecentSlots, Slot{});
    band.accumulators.assign(static_cast<std::size_t>(max_sampled_points), Accumulator{});
    band.cells.assign(static_cast<std::size_t>(max_sampled_points), Eigen::Vector3i::Zero());
    for (std::vector<float>* row : {&band.row_x, &band.row_y, &band.row_z}) row->assign(width, 0.0F);
    for (std::vector<std::int32_t>* row : {&band.row_cell_x, &band.row_cell_y, &band.row_cell_z}) {
      row->assign(width, 0);
    }
  }
  voxel_normals_.assign(static_cast<std::size_t>(max_sampled_points), Eigen::Vector3f::Zero());
  voxel_curvature_.assign(static_cast<std::size_t>(max_sampled_points), 0.0F);
  voxel_normal_support_.assign(static_cast<std::size_t>(max_sampled_points), 0);
  {
    const int stride = std::max(1, config.resolution_pixel_stride);
    neighbour_distances_.assign(static_cast<std::size_t>(sampled_rows(camera.height(), stride)) *
                                    static_cast<std::size_t>(sampled_columns(camera.width(), stride)),
                                0.0);
  }
  blocks_.reserve(camera.width(), camera.height());
  // The camera's rays as two planes (the vectorised row pass loads 8 of each at a time).
  const auto pixels = static_cast<std::size_t>(camera.width()) * static_cast<std::size_t>(camera.height());
  ray_x_.assign(pixels, 0.0F);
  ray_y_.assign(pixels, 0.0F);
  for (int v = 0; v < camera.height(); ++v) {
    for (int u = 0; u < camera.width(); ++u) {
      const Eigen::Vector2f r = camera.ray(u, v);
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(camera.width()) +
                            static_cast<std::size_t>(u);
      ray_x_[i] = r.x();
      ray_y_[i] = r.y();
    }
  }
  block_sums_.reserve(blocks_.width, blocks_.height);
  max_points_ = max_sampled_points;
  return {};
}

SampledCloud CloudPreprocessor::make_cloud() const {
  SampledCloud cloud;
  const auto n = static_cast<std::size_t>(max_points_);
  cloud.points.assign(n, Eigen::Vector3f::Zero());
  cloud.normals.assign(n, Eigen::Vector3f::Zero());
  cloud.pixels.assign(n, Eigen::Vector2f::Zero());
  cloud.curvature.assign(n, 0.0F);
  cloud.dense_counts.assign(n, 0);
  return cloud;
}


namespace {

// One block's points of one row (z = 0: no point), in pixel order: the sums, bounds and count.
void add_block_points_portable(const float* x, const float* y, const float* z, int count,
                               float& sum_x, float& sum_y, float& sum_z, float& min_x,
                               float& min_y, float& min_z, float& max_x, float& max_y,
                               float& max_z, std::int32_t& points) {
  for (int c = 0; c < count; ++c) {
    if (!(z[c] > 0.0F)) continue;
    sum_x += x[c];
    sum_y += y[c];
    sum_z += z[c];
    min_x = std::min(min_x, x[c]);
    min_y = std::min(min_y, y[c]);
    min_z = std::min(min_z, z[c]);
    max_x = std::max(max_x, x[c]);
    max_y = std::max(max_y, y[c]);
    max_z = std::max(max_z, z[c]);
    ++points;
  }
}


}  // namespace

void CloudPreprocessor::BlockSums::reserve(int blocks_per_row, int block_rows) {
  stride = (std::max(0, blocks_per_row) + 7) / 8 * 8;
  const auto n = static_cast<std::size_t>(stride) * static_cast<std::size_t>(std::max(0, block_rows));
  for (std::vector<float>* v : {&sum_x, &sum_y, &sum_z, &min_x, &min_y, &min_z, &max_x, &max_y, &max_z}) {
    v->assign(n, 0.0F);
  }
  count.assign(n, 0);
  clear();
}

void CloudPreprocessor::BlockSums::clear() {
  for (std::vector<float>* v : {&sum_x, &sum_y, &sum_z}) std::fill(v->begin(), v->end(), 0.0F);
  for (std::vector<float>* v : {&min_x, &min_y, &min_z}) {
    std::fill(v->begin(), v->end(), std::numeric_limits<float>::infinity());
  }
  for (std::vector<float>* v : {&max_x, &max_y, &max_z}) {
    std::fill(v->begin(), v->end(), -std::numeric_limits<float>::infinity());
  }
  std::fill(count.begin(), count.end(), 0);
}

void CloudPreprocessor::BlockSums::add_row(const float* x, const float* y, const float* z,
                                           int width, int block_row) {
  constexpr int kBlock = BlockImage::kBlock;
  const int blocks = (width + kBlock - 1) / kBlock;
  const std::size_t first = static_cast<std::size_t>(block_row) * static_cast<std::size_t>(stride);
  int done = 0;
  if (parallel::vector_kernels_enabled()) {
    // Whole groups of blocks that lie inside the row.
    done = vector::add_block_rows(x, y, z, width / kBlock, sum_x.data() + first, sum_y.data() + first,
                                  sum_z.data() + first, min_x.data() + first, min_y.data() + first,
                                  min_z.data() + first, max_x.data() + first, max_y.data() + first,
                                  max_z.data() + first, count.data() + first);
  }
  for (int b = done; b < blocks; ++b) {
    const std::size_t k = first + static_cast<std::size_t>(b);
    const int u = b * kBlock;
    add_block_points_portable(x + u, y + u, z + u, std::min(kBlock, width - u), sum_x[k], sum_y[k],
                              sum_z[k], min_x[k], min_y[k], min_z[k], max_x[k], max_y[k], max_z[k],
                              count[k]);
  }
}

namespace {

// Block b of a layer: `count` points with the given sums and bounds.
void set_block(BlockImage::Layer& layer, std::size_t b, float count, const Eigen::Vector3f& sum,
               const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  const Eigen::Vector3f mean = sum / count;
  const Eigen::Vector3f centre = 0.5F * (min + max);
  const Eigen::Vector3f half = 0.5F * (max - min);
  layer.x[b] = mean.x();
  layer.y[b] = mean.y();
  layer.z[b] = mean.z();
  layer.weight[b] = count;
  layer.centre_x[b] = centre.x();
  layer.centre_y[b] = centre.y();
  layer.centre_z[b] = centre.z();
  layer.half_x[b] = half.x();
  layer.half_y[b] = half.y();
  layer.half_z[b] = half.z();
}

}  // namespace

void CloudPreprocessor::split_block(const cv::Mat& depth, int bu, int bv, float split_z,
                                    std::size_t block) {
  constexpr int kBlock = BlockImage::kBlock;
  const float metres_per_unit = camera_.metres(1);
  const auto min_m = static_cast<float>(config_.min_depth_m);
  const auto max_m = static_cast<float>(config_.max_depth_m);
  struct Part {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    Eigen::Vector3f min = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
    Eigen::Vector3f max = Eigen::Vector3f::Constant(-std::numeric_limits<float>::infinity());
    float count = 0.0F;

    void add(const Eigen::Vector3f& p) {
      sum += p;
      min = min.cwiseMin(p);
      max = max.cwiseMax(p);
      count += 1.0F;
    }
  };
  Part near;
  Part far;
  for (int v = bv * kBlock; v < std::min((bv + 1) * kBlock, depth.rows); ++v) {
    const std::uint16_t* row = depth.ptr<std::uint16_t>(v);
    for (int u = bu * kBlock; u < std::min((bu + 1) * kBlock, depth.cols); ++u) {
      const std::uint16_t raw = row[u];
      if (raw == 0) continue;
      const float z = static_cast<float>(raw) * metres_per_unit;
      if (z < min_m || z > max_m) continue;
      (z <= split_z ? near : far).add(camera_.back_project(u, v, z));
    }
  }
  // Both parts hold points: the block's depths span more than its split leaves on either side.
  set_block(blocks_.front, block, near.count, near.sum, near.min, near.max);
  set_block(blocks_.back, block, far.count, far.sum, far.min, far.max);
}

GeometryStatus CloudPreprocessor::process(const cv::Mat& depth, SampledCloud& cloud) {
  cloud.size = 0;
  cloud.dense_points = 0;
  cloud.dropped_normals = 0;
  if (!configured()) return GeometryStatus::kNotConfigured;
  if (depth.empty() || depth.type() != CV_16UC1 || depth.cols != camera_.width() ||
      depth.rows != camera_.height()) {
    return GeometryStatus::kInvalidImage;
  }
  if (static_cast<int>(cloud.points.size()) < max_points_ ||
      static_cast<int>(cloud.normals.size()) < max_points_ ||
      static_cast<int>(cloud.pixels.size()) < max_points_ ||
      static_cast<int>(cloud.curvature.size()) < max_points_ ||
      static_cast<int>(cloud.dense_counts.size()) < max_points_) {
    return GeometryStatus::kCapacityExceeded;
  }
  const float phi = resolution(depth);
  cloud.resolution_m = phi;
  if (!(phi > 0.0F)) return GeometryStatus::kTooFewPoints;
  float leaf = std::clamp(static_cast<float>(config_.voxel_leaf_factor) * phi,
                          static_cast<float>(config_.min_voxel_leaf_m),
                          static_cast<float>(config_.max_voxel_leaf_m));
  int voxels = 0;
  int dense = 0;
  bool fitted = false;
  for (int attempt = 0; attempt < kVoxelAttempts && !fitted; ++attempt) {
    fitted = voxelise(depth, leaf, voxels, dense);
    if (!fitted) {
      if (leaf >= static_cast<float>(config_.max_voxel_leaf_m)) break;
      leaf = std::min(leaf * kLeafGrowth, static_cast<float>(config_.max_voxel_leaf_m));
    }
  }
  if (!fitted) return GeometryStatus::kCapacityExceeded;
  cloud.voxel_leaf_m = leaf;
  cloud.dense_points = dense;
  const float radius = static_cast<float>(config_.normal_radius_factor) * leaf;
  cloud.normal_radius_m = radius;

  // Block means and bounds. A block whose depths span more than a 80° slope across it (plus the
  // sensor's quantisation) straddles a depth edge: its mean floats between two surfaces.
  const float block_span_per_m =
      static_cast<float>(BlockImage::kBlock) / static_cast<float>(camera_.calibration().fx);
  // Block rows on whichever thread: each block is written by itself.
  const auto block_rows = [&](int first_row, int end_row, int /*thread*/) {
    for (int bv = first_row; bv < end_row; ++bv) {
      for (int bu = 0; bu < blocks_.width; ++bu) {
        const std::size_t k = static_cast<std::size_t>(bv) * static_cast<std::size_t>(block_sums_.stride) +
                              static_cast<std::size_t>(bu);
        const std::size_t b = blocks_.index(bu, bv);
        blocks_.front.weight[b] = 0.0F;
        blocks_.back.weight[b] = 0.0F;
        if (block_sums_.count[k] == 0) continue;
        const auto count = static_cast<float>(block_sums_.count[k]);
        const Eigen::Vector3f sum(block_sums_.sum_x[k], block_sums_.sum_y[k], block_sums_.sum_z[k]);
        const Eigen::Vector3f min(block_sums_.min_x[k], block_sums_.min_y[k], block_sums_.min_z[k]);
        const Eigen::Vector3f max(block_sums_.max_x[k], block_sums_.max_y[k], block_sums_.max_z[k]);
        const float mean_z = sum.z() / count;
        const float max_span = 6.0F * block_span_per_m * mean_z + 3e-3F * mean_z * mean_z;
        if (max.z() - min.z() > max_span) {
          split_block(depth, bu, bv, 0.5F * (min.z() + max.z()), b);
        } else {
          set_block(blocks_.front, b, count, sum, min, max);
        }
      }
    }
  };
  constexpr int kBlockRowsPerChunk = 8;
  parallel::for_chunks(team_, blocks_.height, kBlockRowsPerChunk, block_rows);

  // Each voxel's normal on whichever thread, then the voxels with enough support packed in
  // voxel order.
  constexpr int kVoxelsPerChunk = 64;
  const auto fx = static_cast<float>(camera_.calibration().fx);
  const auto estimate_normals = [&](int begin, int end, int /*thread*/) {
    for (int i = begin; i < end; ++i) {
      const auto k = static_cast<std::size_t>(i);
      const Accumulator& a = bands_[0].accumulators[k];
      const float inverse_f = 1.0F / static_cast<float>(a.count);
      const Eigen::Vector3f center(a.x * inverse_f, a.y * inverse_f, a.z * inverse_f);
      const Eigen::Vector2f pixel(a.u * inverse_f, a.v * inverse_f);
      voxel_normal_support_[k] =
          organised_normal(blocks_, fx, center, pixel, radius, config_.normal_samples_per_axis,
                           voxel_normals_[k], &voxel_curvature_[k]);
    }
  };
  parallel::for_chunks(team_, voxels, kVoxelsPerChunk, estimate_normals);
  int kept = 0;
  for (int i = 0; i < voxels; ++i) {
    const auto v = static_cast<std::size_t>(i);
    if (voxel_normal_support_[v] < config_.normal_min_neighbours) {
      ++cloud.dropped_normals;
      continue;
    }
    const Accumulator& a = bands_[0].accumulators[v];
    const float inverse_f = 1.0F / static_cast<float>(a.count);
    const auto k = static_cast<std::size_t>(kept++);
    cloud.points[k] = Eigen::Vector3f(a.x * inverse_f, a.y * inverse_f, a.z * inverse_f);
    cloud.normals[k] = voxel_normals_[v];
    cloud.pixels[k] = Eigen::Vector2f(a.u * inverse_f, a.v * inverse_f);
    cloud.curvature[k] = voxel_curvature_[v];
    cloud.dense_counts[k] = a.count;
  }
  cloud.size = kept;
  return kept >= 3 ? GeometryStatus::kOk : GeometryStatus::kTooFewPoints;
}

}  // namespace rankslam::geometry
