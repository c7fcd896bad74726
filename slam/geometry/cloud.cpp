#include "rankslam/geometry/cloud.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS 1
#endif

#include "rankslam/geometry/point_grid.hpp"

namespace rankslam::geometry {

namespace {

// Lens distortion changes the pixel footprint of a metric radius by a few per cent over the
// image (fr1's barrel distortion shrinks it toward the corners); the window is widened by this
// factor so that it always covers the radius.
constexpr float kWindowMargin = 1.05F;
// Voxelisation retries with a 25 % larger leaf when the voxels exceed the capacity.
constexpr int kVoxelAttempts = 6;
constexpr float kLeafGrowth = 1.25F;

// ⌊v⌋ without branches for the per-pixel loop, exact for |v| < 2^20: a pass-through point
// (≤ 20 m, ray slope < 10) over a leaf ≥ 1 mm stays far inside that.
inline std::int32_t fast_floor(float v) {
  constexpr double kOffset = 1048576.0;
  return static_cast<std::int32_t>(static_cast<double>(v) + kOffset) - 1048576;
}

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

void BlockImage::Layer::reserve(std::size_t blocks) {
  for (std::vector<float>* v : {&x, &y, &z, &weight, &centre_x, &centre_y, &centre_z, &half_x, &half_y, &half_z}) {
    v->assign(blocks, 0.0F);
  }
}

void BlockImage::reserve(int image_width, int image_height) {
  width = (std::max(0, image_width) + kBlock - 1) / kBlock;
  height = (std::max(0, image_height) + kBlock - 1) / kBlock;
  stride = width + kPad;
  const auto n = static_cast<std::size_t>(stride) * static_cast<std::size_t>(height);
  front.reserve(n);
  back.reserve(n);
}

namespace {

// Weighted moments of points relative to the normal's centre.
struct Moments {
  float n = 0.0F;
  float sx = 0.0F, sy = 0.0F, sz = 0.0F;
  float sxx = 0.0F, sxy = 0.0F, sxz = 0.0F, syy = 0.0F, syz = 0.0F, szz = 0.0F;

  void add(const Eigen::Vector3f& d, float w) {
    n += w;
    sx += w * d.x();
    sy += w * d.y();
    sz += w * d.z();
    sxx += w * d.x() * d.x();
    sxy += w * d.x() * d.y();
    sxz += w * d.x() * d.z();
    syy += w * d.y() * d.y();
    syz += w * d.y() * d.z();
    szz += w * d.z() * d.z();
  }
};

// A block's share of a sphere of squared radius r2 around the centre, from the nearest and
// farthest squared distances of its bounding box: 1 inside, 0 outside, in between the share of
// that range inside the radius (a soft boundary about one block wide).
float soft_share(float near2, float far2, float r2) {
  return std::clamp((r2 - near2) / std::max(far2 - near2, 1e-12F), 0.0F, 1.0F);
}

using Lanes = Eigen::Array4f;  // one SSE / NEON register

Lanes soft_share(const Lanes& near2, const Lanes& far2, float r2) {
  return ((r2 - near2) / (far2 - near2).max(1e-12F)).max(0.0F).min(1.0F);
}

// Along one axis, the nearest and farthest distances from 0 to a bounding box's extent with
// centre `centre` (relative to 0) and half extent `half`, squared and added.
EIGEN_ALWAYS_INLINE void extent_range(const Lanes& centre, const Lanes& half, Lanes& near2, Lanes& far2) {
  const Lanes distance = centre.abs();
  const Lanes near = (distance - half).max(0.0F);
  const Lanes far = distance + half;
  near2 += near * near;
  far2 += far * far;
}

// One layer's block b added to the moments by its share of the sphere (the strided window).
inline void add_block(const BlockImage::Layer& layer, std::size_t b, const Eigen::Vector3f& center,
                      float r2, Moments& m) {
  const float w = layer.weight[b];
  if (w == 0.0F) return;
  const Eigen::Vector3f distance =
      (Eigen::Vector3f(layer.centre_x[b], layer.centre_y[b], layer.centre_z[b]) - center).cwiseAbs();
  const Eigen::Vector3f half(layer.half_x[b], layer.half_y[b], layer.half_z[b]);
  const float near2 = (distance - half).cwiseMax(0.0F).squaredNorm();
  if (near2 > r2) return;
  const float far2 = (distance + half).squaredNorm();
  m.add(layer.mean(b) - center, w * soft_share(near2, far2, r2));
}

// The 4 blocks of one layer from block b on, lanes past `valid` weighing nothing, added to the
// lane sums by their shares of the sphere.
struct LaneMoments {
  Lanes n = Lanes::Zero(), sx = Lanes::Zero(), sy = Lanes::Zero(), sz = Lanes::Zero();
  Lanes sxx = Lanes::Zero(), sxy = Lanes::Zero(), sxz = Lanes::Zero(), syy = Lanes::Zero(),
        syz = Lanes::Zero(), szz = Lanes::Zero();

  EIGEN_ALWAYS_INLINE void add(const BlockImage::Layer& layer, std::size_t b, const Eigen::Vector3f& center,
                               float r2, const Lanes& valid) {
    const Lanes w0 = Eigen::Map<const Lanes>(layer.weight.data() + b) * valid;
    const Lanes dx = Eigen::Map<const Lanes>(layer.x.data() + b) - center.x();
    const Lanes dy = Eigen::Map<const Lanes>(layer.y.data() + b) - center.y();
    const Lanes dz = Eigen::Map<const Lanes>(layer.z.data() + b) - center.z();
    Lanes near2 = Lanes::Zero();
    Lanes far2 = Lanes::Zero();
    extent_range(Eigen::Map<const Lanes>(layer.centre_x.data() + b) - center.x(),
                 Eigen::Map<const Lanes>(layer.half_x.data() + b), near2, far2);
    extent_range(Eigen::Map<const Lanes>(layer.centre_y.data() + b) - center.y(),
                 Eigen::Map<const Lanes>(layer.half_y.data() + b), near2, far2);
    extent_range(Eigen::Map<const Lanes>(layer.centre_z.data() + b) - center.z(),
                 Eigen::Map<const Lanes>(layer.half_z.data() + b), near2, far2);
    const Lanes w = w0 * soft_share(near2, far2, r2);
    n += w;
    sx += w * dx;
    sy += w * dy;
    sz += w * dz;
    sxx += w * dx * dx;
    sxy += w * dx * dy;
    sxz += w * dx * dz;
    syy += w * dy * dy;
    syz += w * dy * dz;
    szz += w * dz * dz;
  }

  void add_to(Moments& m) const {
    m.n += n.sum();
    m.sx += sx.sum();
    m.sy += sy.sum();
    m.sz += sz.sum();
    m.sxx += sxx.sum();
    m.sxy += sxy.sum();
    m.sxz += sxz.sum();
    m.syy += syy.sum();
    m.syz += syz.sum();
    m.szz += szz.sum();
  }
};

#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
__attribute__((target("avx2,fma"))) float horizontal_sum(__m256 v) {
  const __m128 lo = _mm256_castps256_ps128(v);
  const __m128 hi = _mm256_extractf128_ps(v, 1);
  __m128 s = _mm_add_ps(lo, hi);
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 0x55));
  return _mm_cvtss_f32(s);
}

// LaneMoments::add, 8 blocks at a time (AVX2 and FMA, chosen at run time): sums[] holds n, sx,
// sy, sz, sxx, sxy, sxz, syy, syz, szz per lane.
__attribute__((target("avx2,fma"), always_inline)) inline void add_blocks_avx2(
    const BlockImage::Layer& layer, std::size_t b, const __m256 (&center)[3], __m256 radius2,
    __m256 valid, __m256 (&sums)[10]) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256 magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const std::array<const float*, 3> mean = {layer.x.data(), layer.y.data(), layer.z.data()};
  const std::array<const float*, 3> centre = {layer.centre_x.data(), layer.centre_y.data(), layer.centre_z.data()};
  const std::array<const float*, 3> half = {layer.half_x.data(), layer.half_y.data(), layer.half_z.data()};
  const __m256 w0 = _mm256_and_ps(_mm256_loadu_ps(layer.weight.data() + b), valid);
  __m256 d[3];
  __m256 near2 = zero;
  __m256 far2 = zero;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    d[axis] = _mm256_sub_ps(_mm256_loadu_ps(mean[axis] + b), center[axis]);
    const __m256 distance = _mm256_and_ps(_mm256_sub_ps(_mm256_loadu_ps(centre[axis] + b), center[axis]), magnitude);
    const __m256 extent = _mm256_loadu_ps(half[axis] + b);
    const __m256 near = _mm256_max_ps(_mm256_sub_ps(distance, extent), zero);
    const __m256 far = _mm256_add_ps(distance, extent);
    near2 = _mm256_fmadd_ps(near, near, near2);
    far2 = _mm256_fmadd_ps(far, far, far2);
  }
  const __m256 share = _mm256_min_ps(
      _mm256_max_ps(_mm256_div_ps(_mm256_sub_ps(radius2, near2),
                                  _mm256_max_ps(_mm256_sub_ps(far2, near2), _mm256_set1_ps(1e-12F))),
                    zero),
      _mm256_set1_ps(1.0F));
  const __m256 w = _mm256_mul_ps(w0, share);
  const __m256 wd[3] = {_mm256_mul_ps(w, d[0]), _mm256_mul_ps(w, d[1]), _mm256_mul_ps(w, d[2])};
  sums[0] = _mm256_add_ps(sums[0], w);
  sums[1] = _mm256_add_ps(sums[1], wd[0]);
  sums[2] = _mm256_add_ps(sums[2], wd[1]);
  sums[3] = _mm256_add_ps(sums[3], wd[2]);
  sums[4] = _mm256_fmadd_ps(wd[0], d[0], sums[4]);
  sums[5] = _mm256_fmadd_ps(wd[0], d[1], sums[5]);
  sums[6] = _mm256_fmadd_ps(wd[0], d[2], sums[6]);
  sums[7] = _mm256_fmadd_ps(wd[1], d[1], sums[7]);
  sums[8] = _mm256_fmadd_ps(wd[1], d[2], sums[8]);
  sums[9] = _mm256_fmadd_ps(wd[2], d[2], sums[9]);
}

// 8 blocks of a window row from `block` on, the first `lanes` of them inside the window.
struct WindowGroup {
  std::int32_t block;
  float lanes;
};

// The groups' blocks of both layers added to the lane sums, in order.
__attribute__((target("avx2,fma"), always_inline)) inline void sum_window_groups(
    const BlockImage& blocks, const WindowGroup* groups, int count, const __m256 (&center)[3],
    __m256 radius2, __m256 (&sums)[10]) {
  const __m256 lane_index = _mm256_setr_ps(0.0F, 1.0F, 2.0F, 3.0F, 4.0F, 5.0F, 6.0F, 7.0F);
  for (int g = 0; g < count; ++g) {
    const auto b = static_cast<std::size_t>(groups[g].block);
    const __m256 valid = _mm256_cmp_ps(lane_index, _mm256_set1_ps(groups[g].lanes), _CMP_LT_OQ);
    add_blocks_avx2(blocks.front, b, center, radius2, valid, sums);
    const __m256 back = _mm256_and_ps(_mm256_loadu_ps(blocks.back.weight.data() + b), valid);
    if (_mm256_movemask_ps(_mm256_cmp_ps(back, _mm256_setzero_ps(), _CMP_GT_OQ)) != 0) {
      add_blocks_avx2(blocks.back, b, center, radius2, valid, sums);
    }
  }
}

// The unstrided window of organised_normal, 8 blocks of a row at a time (AVX2 and FMA, chosen
// at run time): the same sums as the portable 4-block loop there, in another order and with
// fused multiply-adds (normals within 0.1° of it, test/unit/geometry normals_test). The far
// parts of blocks across depth edges are added where a group of 8 has any.
__attribute__((target("avx2,fma"))) void window_moments_avx2(const BlockImage& blocks,
                                                              const Eigen::Vector3f& center, int bu,
                                                              int bv, int steps, float half_blocks,
                                                              float r2, Moments& m) {
  const __m256 radius2 = _mm256_set1_ps(r2);
  const __m256 c[3] = {_mm256_set1_ps(center.x()), _mm256_set1_ps(center.y()), _mm256_set1_ps(center.z())};
  __m256 sums[10];
  for (__m256& sum : sums) sum = _mm256_setzero_ps();
  // The window's groups of 8 blocks are listed first (rows ascending, then columns), then summed
  // in one loop: the rows' varying group counts would otherwise end each row's loop on a
  // mispredicted branch in the middle of the vector work.
  constexpr int kMaxGroups = 64;
  std::array<WindowGroup, kMaxGroups> groups;
  int listed = 0;
  const float reach = half_blocks + 1.0F;
  for (int v = std::max(bv - steps, 0); v <= std::min(bv + steps, blocks.height - 1); ++v) {
    const auto dv = static_cast<float>(v - bv);
    const int span = static_cast<int>(std::sqrt(std::max(0.0F, reach * reach - dv * dv)));
    const int u_lo = std::max(bu - span, 0);
    const int u_hi = std::min(bu + span, blocks.width - 1);
    for (int u = u_lo; u <= u_hi; u += 8) {
      if (listed == kMaxGroups) {
        sum_window_groups(blocks, groups.data(), listed, c, radius2, sums);
        listed = 0;
      }
      groups[static_cast<std::size_t>(listed++)] =
          WindowGroup{static_cast<std::int32_t>(blocks.index(u, v)), static_cast<float>(u_hi - u + 1)};
    }
  }
  sum_window_groups(blocks, groups.data(), listed, c, radius2, sums);
  m.n += horizontal_sum(sums[0]);
  m.sx += horizontal_sum(sums[1]);
  m.sy += horizontal_sum(sums[2]);
  m.sz += horizontal_sum(sums[3]);
  m.sxx += horizontal_sum(sums[4]);
  m.sxy += horizontal_sum(sums[5]);
  m.sxz += horizontal_sum(sums[6]);
  m.syy += horizontal_sum(sums[7]);
  m.syz += horizontal_sum(sums[8]);
  m.szz += horizontal_sum(sums[9]);
}
#endif

// One image row of the voxel grid's pass: every pixel's camera-frame point and voxel
// coordinates, z = 0 where the pixel is empty or outside the pass-through.
struct RowPoints {
  float* x;
  float* y;
  float* z;
  std::int32_t* cell_x;
  std::int32_t* cell_y;
  std::int32_t* cell_z;
};

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

#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
// prepare_row_portable, 8 pixels at a time (AVX2, chosen at run time): the same products, and
// the floor of the same float values, so the same points and voxels.
__attribute__((target("avx2"))) void prepare_row_avx2(const std::uint16_t* raw, const float* ray_x,
                                                      const float* ray_y, int width,
                                                      float metres_per_unit, float min_m, float max_m,
                                                      float inverse_leaf, const RowPoints& out) {
  const __m256 scale = _mm256_set1_ps(metres_per_unit);
  const __m256 lo = _mm256_set1_ps(min_m);
  const __m256 hi = _mm256_set1_ps(max_m);
  const __m256 inverse = _mm256_set1_ps(inverse_leaf);
  const __m256 zero = _mm256_setzero_ps();
  int u = 0;
  for (; u + 8 <= width; u += 8) {
    const __m256 raw_f = _mm256_cvtepi32_ps(
        _mm256_cvtepu16_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(raw + u))));
    const __m256 z = _mm256_mul_ps(raw_f, scale);
    const __m256 valid =
        _mm256_and_ps(_mm256_cmp_ps(raw_f, zero, _CMP_NEQ_OQ),
                      _mm256_and_ps(_mm256_cmp_ps(z, lo, _CMP_GE_OQ), _mm256_cmp_ps(z, hi, _CMP_LE_OQ)));
    const __m256 x = _mm256_mul_ps(_mm256_loadu_ps(ray_x + u), z);
    const __m256 y = _mm256_mul_ps(_mm256_loadu_ps(ray_y + u), z);
    _mm256_storeu_ps(out.x + u, x);
    _mm256_storeu_ps(out.y + u, y);
    _mm256_storeu_ps(out.z + u, _mm256_and_ps(valid, z));
    const __m256i mask = _mm256_castps_si256(valid);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.cell_x + u),
                        _mm256_and_si256(mask, _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_mul_ps(x, inverse)))));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.cell_y + u),
                        _mm256_and_si256(mask, _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_mul_ps(y, inverse)))));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.cell_z + u),
                        _mm256_and_si256(mask, _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_mul_ps(z, inverse)))));
  }
  prepare_row_portable(raw, ray_x, ray_y, width, metres_per_unit, min_m, max_m, inverse_leaf, out, u);
}
#endif

}  // namespace

int organised_normal(const BlockImage& blocks, float fx, const Eigen::Vector3f& center,
                     const Eigen::Vector2f& pixel, float radius_m, int samples_per_axis,
                     Eigen::Vector3f& normal, float* curvature, bool best_kernel) {
  if (!(center.z() > 0.0F) || !(radius_m > 0.0F) || samples_per_axis < 1 || blocks.width < 1) {
    return 0;
  }
  constexpr auto kBlockF = static_cast<float>(BlockImage::kBlock);
  const float half_blocks = radius_m * fx / center.z() * kWindowMargin / kBlockF;
  const int stride = std::max(
      1, static_cast<int>(std::lround(2.0F * half_blocks / static_cast<float>(samples_per_axis))));
  const int steps = static_cast<int>(std::ceil(half_blocks)) / stride;
  const int bu = static_cast<int>(pixel.x() / kBlockF);
  const int bv = static_cast<int>(pixel.y() / kBlockF);
  const float r2 = radius_m * radius_m;

  Moments m;
#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
  const bool avx2 = best_kernel && parallel::cpu_has_avx2_fma();
#else
  const bool avx2 = false;
  (void)best_kernel;
#endif
  if (stride == 1 && avx2) {
#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
    window_moments_avx2(blocks, center, bu, bv, steps, half_blocks, r2, m);
#endif
  } else if (stride == 1) {
    // Rows of the window 4 blocks at a time (the rows' padding keeps the reads in bounds).
    const Lanes lane_index(0.0F, 1.0F, 2.0F, 3.0F);
    LaneMoments sums;
    // The radius' pixel footprint is a disc: each row of the window only as wide as the disc
    // there (plus a block for the blocks' own extent).
    const float reach = half_blocks + 1.0F;
    for (int v = std::max(bv - steps, 0); v <= std::min(bv + steps, blocks.height - 1); ++v) {
      const auto dv = static_cast<float>(v - bv);
      const int span = static_cast<int>(std::sqrt(std::max(0.0F, reach * reach - dv * dv)));
      const int u_lo = std::max(bu - span, 0);
      const int u_hi = std::min(bu + span, blocks.width - 1);
      for (int u = u_lo; u <= u_hi; u += 4) {
        const std::size_t b = blocks.index(u, v);
        const Lanes valid = (lane_index < static_cast<float>(u_hi - u + 1)).cast<float>();
        sums.add(blocks.front, b, center, r2, valid);
        if ((Eigen::Map<const Lanes>(blocks.back.weight.data() + b) * valid > 0.0F).any()) {
          sums.add(blocks.back, b, center, r2, valid);
        }
      }
    }
    sums.add_to(m);
  } else {
    // A near point's wide window: every stride-th block.
    for (int j = -steps; j <= steps; ++j) {
      const int v = bv + j * stride;
      if (v < 0 || v >= blocks.height) continue;
      for (int i = -steps; i <= steps; ++i) {
        const int u = bu + i * stride;
        if (u < 0 || u >= blocks.width) continue;
        const std::size_t b = blocks.index(u, v);
        add_block(blocks.front, b, center, r2, m);
        add_block(blocks.back, b, center, r2, m);
      }
    }
  }
  const int count = static_cast<int>(m.n);
  if (count < 3) return count;
  const Eigen::Vector3f mean = Eigen::Vector3f(m.sx, m.sy, m.sz) / m.n;
  Eigen::Matrix3f cov;
  cov << m.sxx / m.n, m.sxy / m.n, m.sxz / m.n, m.sxy / m.n, m.syy / m.n, m.syz / m.n,
      m.sxz / m.n, m.syz / m.n, m.szz / m.n;
  cov -= mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> solver;
  solver.computeDirect(cov);
  Eigen::Vector3f result = solver.eigenvectors().col(0);
  const float length = result.norm();
  if (!(length > 0.0F) || !std::isfinite(length)) return 0;
  result /= length;
  // Toward the camera at the origin: (0 − p)·n > 0.
  if (result.dot(center) > 0.0F) result = -result;
  normal = result;
  if (curvature != nullptr) {
    const float total = solver.eigenvalues().sum();
    *curvature = total > 0.0F ? std::max(0.0F, solver.eigenvalues()(0)) / total : 0.0F;
  }
  return count;
}

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
#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
  const bool avx2 = parallel::cpu_has_avx2();
#endif
  const RowPoints row_points{band.row_x.data(), band.row_y.data(), band.row_z.data(),
                             band.row_cell_x.data(), band.row_cell_y.data(), band.row_cell_z.data()};
  for (int v = row_begin; v < row_end; ++v) {
    const std::uint16_t* row = depth.ptr<std::uint16_t>(v);
    // The points and voxel coordinates of the row first (vectorised where the CPU allows),
    // then the hashing and sums, which depend on the previous pixel's voxel.
    const std::size_t row_start = static_cast<std::size_t>(v) * static_cast<std::size_t>(depth.cols);
#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
    if (avx2) {
      prepare_row_avx2(row, ray_x_.data() + row_start, ray_y_.data() + row_start, depth.cols,
                       metres_per_unit, min_m, max_m, inverse_leaf, row_points);
    } else {
      prepare_row_portable(row, ray_x_.data() + row_start, ray_y_.data() + row_start, depth.cols,
                           metres_per_unit, min_m, max_m, inverse_leaf, row_points);
    }
#else
    prepare_row_portable(row, ray_x_.data() + row_start, ray_y_.data() + row_start, depth.cols,
                         metres_per_unit, min_m, max_m, inverse_leaf, row_points);
#endif
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

#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
// The 4 pixels of 8 consecutive blocks (32 pixels from `row`) as 4 vectors, vector c holding
// pixel c of blocks 0..7 in order.
__attribute__((target("avx2"))) inline void pixels_of_8_blocks(const float* row, __m256 (&pixel)[4]) {
  const __m256 v0 = _mm256_loadu_ps(row);       // blocks 0, 1
  const __m256 v1 = _mm256_loadu_ps(row + 8);   // blocks 2, 3
  const __m256 v2 = _mm256_loadu_ps(row + 16);  // blocks 4, 5
  const __m256 v3 = _mm256_loadu_ps(row + 24);  // blocks 6, 7
  const __m256 t0 = _mm256_unpacklo_ps(v0, v1);
  const __m256 t1 = _mm256_unpackhi_ps(v0, v1);
  const __m256 t2 = _mm256_unpacklo_ps(v2, v3);
  const __m256 t3 = _mm256_unpackhi_ps(v2, v3);
  // The shuffles leave blocks in the order 0 2 4 6 1 3 5 7.
  const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
  pixel[0] = _mm256_permutevar8x32_ps(_mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0)), order);
  pixel[1] = _mm256_permutevar8x32_ps(_mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2)), order);
  pixel[2] = _mm256_permutevar8x32_ps(_mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0)), order);
  pixel[3] = _mm256_permutevar8x32_ps(_mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2)), order);
}

// add_block_points_portable for 8 blocks at a time (AVX2, chosen at run time): each block's
// points added in the same order, no point added as +0 (which leaves a sum that started at +0
// unchanged) and bounded as ±infinity, so the same sums and bounds. Returns the blocks done.
__attribute__((target("avx2"))) int add_row_avx2(const float* x, const float* y, const float* z,
                                                 int blocks, float* sum_x, float* sum_y,
                                                 float* sum_z, float* min_x, float* min_y,
                                                 float* min_z, float* max_x, float* max_y,
                                                 float* max_z, std::int32_t* count) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256 infinity = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  const __m256 minus_infinity = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
  int b = 0;
  for (; b + 8 <= blocks; b += 8) {
    const int first_pixel = b * BlockImage::kBlock;
    __m256 px[4];
    __m256 py[4];
    __m256 pz[4];
    pixels_of_8_blocks(x + first_pixel, px);
    pixels_of_8_blocks(y + first_pixel, py);
    pixels_of_8_blocks(z + first_pixel, pz);
    __m256 sx = _mm256_loadu_ps(sum_x + b), sy = _mm256_loadu_ps(sum_y + b), sz = _mm256_loadu_ps(sum_z + b);
    __m256 lx = _mm256_loadu_ps(min_x + b), ly = _mm256_loadu_ps(min_y + b), lz = _mm256_loadu_ps(min_z + b);
    __m256 hx = _mm256_loadu_ps(max_x + b), hy = _mm256_loadu_ps(max_y + b), hz = _mm256_loadu_ps(max_z + b);
    __m256i n = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(count + b));
    for (int c = 0; c < BlockImage::kBlock; ++c) {
      const __m256 valid = _mm256_cmp_ps(pz[c], zero, _CMP_GT_OQ);
      sx = _mm256_add_ps(sx, _mm256_and_ps(valid, px[c]));
      sy = _mm256_add_ps(sy, _mm256_and_ps(valid, py[c]));
      sz = _mm256_add_ps(sz, _mm256_and_ps(valid, pz[c]));
      lx = _mm256_min_ps(lx, _mm256_blendv_ps(infinity, px[c], valid));
      ly = _mm256_min_ps(ly, _mm256_blendv_ps(infinity, py[c], valid));
      lz = _mm256_min_ps(lz, _mm256_blendv_ps(infinity, pz[c], valid));
      hx = _mm256_max_ps(hx, _mm256_blendv_ps(minus_infinity, px[c], valid));
      hy = _mm256_max_ps(hy, _mm256_blendv_ps(minus_infinity, py[c], valid));
      hz = _mm256_max_ps(hz, _mm256_blendv_ps(minus_infinity, pz[c], valid));
      n = _mm256_sub_epi32(n, _mm256_castps_si256(valid));  // valid lanes are −1
    }
    _mm256_storeu_ps(sum_x + b, sx);
    _mm256_storeu_ps(sum_y + b, sy);
    _mm256_storeu_ps(sum_z + b, sz);
    _mm256_storeu_ps(min_x + b, lx);
    _mm256_storeu_ps(min_y + b, ly);
    _mm256_storeu_ps(min_z + b, lz);
    _mm256_storeu_ps(max_x + b, hx);
    _mm256_storeu_ps(max_y + b, hy);
    _mm256_storeu_ps(max_z + b, hz);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(count + b), n);
  }
  return b;
}
#endif

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
#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_NORMALS
  if (parallel::cpu_has_avx2()) {
    // Whole groups of 8 blocks that lie inside the row.
    done = add_row_avx2(x, y, z, width / kBlock, sum_x.data() + first, sum_y.data() + first,
                        sum_z.data() + first, min_x.data() + first, min_y.data() + first,
                        min_z.data() + first, max_x.data() + first, max_y.data() + first,
                        max_z.data() + first, count.data() + first);
  }
#endif
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
