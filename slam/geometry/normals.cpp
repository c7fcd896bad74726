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

// Normals from the block image of the organised depth image: the moments of the blocks inside a
// metric radius around a point, portable 4 blocks at a time or AVX2 8 at a time.
namespace rankslam::geometry {

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

// Lens distortion changes the pixel footprint of a metric radius by a few per cent over the
// image (fr1's barrel distortion shrinks it toward the corners); the window is widened by this
// factor so that it always covers the radius.
constexpr float kWindowMargin = 1.05F;

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

}  // namespace rankslam::geometry
