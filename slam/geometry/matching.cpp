#include "rankslam/geometry/matching.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define RANKSLAM_GEOMETRY_HAVE_AVX2_KERNEL 1
#endif

namespace rankslam::geometry {

namespace {

// The best so far of a block of A's rows (best_a, arg_a start at the block's first row) and of
// every row of B over that block (arg_b holds indices into the whole of A).
struct Best {
  float* best_a;
  int* arg_a;
  float* best_b;
  int* arg_b;
  int row_offset;
};

// Strictly greater keeps the lower index on ties, since rows and columns are visited ascending.
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

// Portable kernel: 2 × 2 blocks of dot products, 8 independent lanes each, as Eigen fixed-size
// packets (SSE2 / NEON).
void scan_portable(const float* a, int na, const float* b, int nb, int dim, Best& best) {
  using Lanes = Eigen::Array<float, 8, 1>;
  const int vector_end = dim - dim % 8;
  const auto dot_tail = [&](const float* x, const float* y) {
    float s = 0.0F;
    for (int k = vector_end; k < dim; ++k) s += x[k] * y[k];
    return s;
  };
  int i = 0;
  for (; i + 1 < na; i += 2) {
    const float* a0 = a + static_cast<std::ptrdiff_t>(i) * dim;
    const float* a1 = a0 + dim;
    int j = 0;
    for (; j + 1 < nb; j += 2) {
      const float* b0 = b + static_cast<std::ptrdiff_t>(j) * dim;
      const float* b1 = b0 + dim;
      Lanes s00 = Lanes::Zero(), s01 = Lanes::Zero(), s10 = Lanes::Zero(), s11 = Lanes::Zero();
      for (int k = 0; k < vector_end; k += 8) {
        const Lanes x0 = Eigen::Map<const Lanes>(a0 + k);
        const Lanes x1 = Eigen::Map<const Lanes>(a1 + k);
        const Lanes y0 = Eigen::Map<const Lanes>(b0 + k);
        const Lanes y1 = Eigen::Map<const Lanes>(b1 + k);
        s00 += x0 * y0;
        s01 += x0 * y1;
        s10 += x1 * y0;
        s11 += x1 * y1;
      }
      update(best, i, j, s00.sum() + dot_tail(a0, b0));
      update(best, i, j + 1, s01.sum() + dot_tail(a0, b1));
      update(best, i + 1, j, s10.sum() + dot_tail(a1, b0));
      update(best, i + 1, j + 1, s11.sum() + dot_tail(a1, b1));
    }
    for (; j < nb; ++j) {
      const float* b0 = b + static_cast<std::ptrdiff_t>(j) * dim;
      float s0 = 0.0F, s1 = 0.0F;
      for (int k = 0; k < dim; ++k) {
        s0 += a0[k] * b0[k];
        s1 += a1[k] * b0[k];
      }
      update(best, i, j, s0);
      update(best, i + 1, j, s1);
    }
  }
  for (; i < na; ++i) {
    const float* a0 = a + static_cast<std::ptrdiff_t>(i) * dim;
    for (int j = 0; j < nb; ++j) {
      const float* b0 = b + static_cast<std::ptrdiff_t>(j) * dim;
      float s = 0.0F;
      for (int k = 0; k < dim; ++k) s += a0[k] * b0[k];
      update(best, i, j, s);
    }
  }
}

#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_KERNEL
__attribute__((target("avx2,fma"))) inline float horizontal_sum(__m256 v) {
  const __m128 lo = _mm256_castps256_ps128(v);
  const __m128 hi = _mm256_extractf128_ps(v, 1);
  __m128 s = _mm_add_ps(lo, hi);
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 0x55));
  return _mm_cvtss_f32(s);
}

// 4 × 3 blocks: 12 accumulators, 3 rows of B and one of A in registers (16 of 16 ymm), so that
// each 8-float step loads 7 vectors for 12 FMAs (4 × 2 blocks: 6 loads for 8). The blocks sum
// each dot product in the same order as the 4 × 2 blocks did; only the last nb mod 3 columns
// (nb mod 2 before) go through the one-column loop, which rounds differently. Measured on
// fr1_rpy_head (perf_geometry BM_MatchExhaustive, 400 × 400): 2.10 ms with 4 × 2 blocks, 1.46 ms.
// On a 2 GHz Zen 1 it takes 4.2 ms, about 6.7 of that CPU's peak 8 float multiply-adds per
// cycle; 16-bit fixed point (vpmaddwd) took 5.3 ms there: Zen 1 multiplies integer vectors
// no faster.
__attribute__((target("avx2,fma"))) void scan_avx2(const float* a, int na, const float* b,
                                                   int nb, int dim, Best& best) {
  const int vector_end = dim - dim % 8;
  const auto dot = [dim](const float* x, const float* y, int from) {
    float s = 0.0F;
    for (int k = from; k < dim; ++k) s += x[k] * y[k];
    return s;
  };
  int i = 0;
  for (; i + 3 < na; i += 4) {
    const float* a0 = a + static_cast<std::ptrdiff_t>(i) * dim;
    const float* a1 = a0 + dim;
    const float* a2 = a1 + dim;
    const float* a3 = a2 + dim;
    int j = 0;
    for (; j + 2 < nb; j += 3) {
      const float* b0 = b + static_cast<std::ptrdiff_t>(j) * dim;
      const float* b1 = b0 + dim;
      const float* b2 = b1 + dim;
      __m256 s00 = _mm256_setzero_ps(), s01 = _mm256_setzero_ps(), s02 = _mm256_setzero_ps();
      __m256 s10 = _mm256_setzero_ps(), s11 = _mm256_setzero_ps(), s12 = _mm256_setzero_ps();
      __m256 s20 = _mm256_setzero_ps(), s21 = _mm256_setzero_ps(), s22 = _mm256_setzero_ps();
      __m256 s30 = _mm256_setzero_ps(), s31 = _mm256_setzero_ps(), s32 = _mm256_setzero_ps();
      for (int k = 0; k < vector_end; k += 8) {
        const __m256 y0 = _mm256_loadu_ps(b0 + k);
        const __m256 y1 = _mm256_loadu_ps(b1 + k);
        const __m256 y2 = _mm256_loadu_ps(b2 + k);
        __m256 x = _mm256_loadu_ps(a0 + k);
        s00 = _mm256_fmadd_ps(x, y0, s00);
        s01 = _mm256_fmadd_ps(x, y1, s01);
        s02 = _mm256_fmadd_ps(x, y2, s02);
        x = _mm256_loadu_ps(a1 + k);
        s10 = _mm256_fmadd_ps(x, y0, s10);
        s11 = _mm256_fmadd_ps(x, y1, s11);
        s12 = _mm256_fmadd_ps(x, y2, s12);
        x = _mm256_loadu_ps(a2 + k);
        s20 = _mm256_fmadd_ps(x, y0, s20);
        s21 = _mm256_fmadd_ps(x, y1, s21);
        s22 = _mm256_fmadd_ps(x, y2, s22);
        x = _mm256_loadu_ps(a3 + k);
        s30 = _mm256_fmadd_ps(x, y0, s30);
        s31 = _mm256_fmadd_ps(x, y1, s31);
        s32 = _mm256_fmadd_ps(x, y2, s32);
      }
      update(best, i, j, horizontal_sum(s00) + dot(a0, b0, vector_end));
      update(best, i, j + 1, horizontal_sum(s01) + dot(a0, b1, vector_end));
      update(best, i, j + 2, horizontal_sum(s02) + dot(a0, b2, vector_end));
      update(best, i + 1, j, horizontal_sum(s10) + dot(a1, b0, vector_end));
      update(best, i + 1, j + 1, horizontal_sum(s11) + dot(a1, b1, vector_end));
      update(best, i + 1, j + 2, horizontal_sum(s12) + dot(a1, b2, vector_end));
      update(best, i + 2, j, horizontal_sum(s20) + dot(a2, b0, vector_end));
      update(best, i + 2, j + 1, horizontal_sum(s21) + dot(a2, b1, vector_end));
      update(best, i + 2, j + 2, horizontal_sum(s22) + dot(a2, b2, vector_end));
      update(best, i + 3, j, horizontal_sum(s30) + dot(a3, b0, vector_end));
      update(best, i + 3, j + 1, horizontal_sum(s31) + dot(a3, b1, vector_end));
      update(best, i + 3, j + 2, horizontal_sum(s32) + dot(a3, b2, vector_end));
    }
    for (; j < nb; ++j) {
      const float* b0 = b + static_cast<std::ptrdiff_t>(j) * dim;
      for (int r = 0; r < 4; ++r) update(best, i + r, j, dot(a0 + r * dim, b0, 0));
    }
  }
  for (; i < na; ++i) {
    const float* a0 = a + static_cast<std::ptrdiff_t>(i) * dim;
    for (int j = 0; j < nb; ++j) {
      const float* b0 = b + static_cast<std::ptrdiff_t>(j) * dim;
      __m256 s = _mm256_setzero_ps();
      for (int k = 0; k < vector_end; k += 8) {
        s = _mm256_fmadd_ps(_mm256_loadu_ps(a0 + k), _mm256_loadu_ps(b0 + k), s);
      }
      update(best, i, j, horizontal_sum(s) + dot(a0, b0, vector_end));
    }
  }
}

#endif

}  // namespace

bool DescriptorMatcher::cpu_has_avx2() {
#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_KERNEL
  return parallel::cpu_has_avx2_fma();
#else
  return false;
#endif
}

std::string DescriptorMatcher::configure(int max_descriptors, int dimension, Kernel kernel,
                                         parallel::ThreadTeam* team) {
  capacity_ = 0;
  if (max_descriptors < 1 || max_descriptors > 1'000'000) {
    return "geometry: matcher capacity " + std::to_string(max_descriptors) + " is out of range";
  }
  if (dimension < 1 || dimension > 100'000) {
    return "geometry: descriptor dimension " + std::to_string(dimension) + " is out of range";
  }
  dimension_ = dimension;
  team_ = team;
  const auto n = static_cast<std::size_t>(max_descriptors);
  const auto blocks = static_cast<std::size_t>(parallel::team_size(team));
  best_of_a_.assign(n, 0.0F);
  arg_of_a_.assign(n, -1);
  best_of_b_.assign(n * blocks, 0.0F);
  arg_of_b_.assign(n * blocks, -1);
  use_avx2_ = kernel == Kernel::kBest && cpu_has_avx2();
  capacity_ = max_descriptors;
  return {};
}

int DescriptorMatcher::match(const float* a, int count_a, const float* b, int count_b,
                             std::span<DescriptorMatch> out) {
  if (!configured() || count_a > capacity_ || count_b > capacity_ || count_a < 0 || count_b < 0) {
    return -1;
  }
  if (count_a == 0 || count_b == 0) return 0;
  // A's rows in chunks to whichever thread asks, each thread with its own best of B's rows over
  // the rows it scanned (which come to it in increasing order, so ties within a thread keep the
  // lower row); the threads' bests are then merged, ties again to the lower row. Chunk edges fall
  // on multiples of the kernels' 4 rows, so every dot product is summed as in one pass.
  constexpr int kRowsPerChunk = 32;  // a multiple of the kernels' 4 rows
  const int threads = parallel::team_size(team_);
  constexpr float kLowest = -std::numeric_limits<float>::infinity();
  std::fill_n(best_of_a_.begin(), count_a, kLowest);
  std::fill_n(arg_of_a_.begin(), count_a, -1);
  for (int thread = 0; thread < threads; ++thread) {
    const auto b_offset = static_cast<std::ptrdiff_t>(thread) * capacity_;
    std::fill_n(best_of_b_.begin() + b_offset, count_b, kLowest);
    std::fill_n(arg_of_b_.begin() + b_offset, count_b, -1);
  }
  const auto scan_rows = [&](int first, int end, int thread) {
    const auto b_offset = static_cast<std::ptrdiff_t>(thread) * capacity_;
    Best best{best_of_a_.data() + first, arg_of_a_.data() + first, best_of_b_.data() + b_offset,
              arg_of_b_.data() + b_offset, first};
    const float* rows_of_a = a + static_cast<std::ptrdiff_t>(first) * dimension_;
#ifdef RANKSLAM_GEOMETRY_HAVE_AVX2_KERNEL
    if (use_avx2_) {
      scan_avx2(rows_of_a, end - first, b, count_b, dimension_, best);
    } else {
      scan_portable(rows_of_a, end - first, b, count_b, dimension_, best);
    }
#else
    scan_portable(rows_of_a, end - first, b, count_b, dimension_, best);
#endif
  };
  parallel::for_chunks(team_, count_a, kRowsPerChunk, scan_rows);
  for (int thread = 1; thread < threads; ++thread) {
    const auto b_offset = static_cast<std::size_t>(thread) * static_cast<std::size_t>(capacity_);
    for (int j = 0; j < count_b; ++j) {
      const auto k = static_cast<std::size_t>(j);
      const int row = arg_of_b_[k + b_offset];
      if (row < 0) continue;
      const float similarity = best_of_b_[k + b_offset];
      if (arg_of_b_[k] < 0 || similarity > best_of_b_[k] || (similarity == best_of_b_[k] && row < arg_of_b_[k])) {
        best_of_b_[k] = similarity;
        arg_of_b_[k] = row;
      }
    }
  }
  int count = 0;
  for (int i = 0; i < count_a && count < static_cast<int>(out.size()); ++i) {
    const int j = arg_of_a_[static_cast<std::size_t>(i)];
    if (j < 0 || arg_of_b_[static_cast<std::size_t>(j)] != i) continue;
    const float similarity = best_of_a_[static_cast<std::size_t>(i)];
    out[static_cast<std::size_t>(count++)] =
        DescriptorMatch{i, j, std::sqrt(std::max(0.0F, 2.0F - 2.0F * similarity))};
  }
  return count;
}

}  // namespace rankslam::geometry
