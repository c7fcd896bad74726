#include "rankslam/geometry/matching.hpp"

#include "rankslam/parallel/cpu_features.hpp"
#include "vector_kernels.hpp"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <cstring>
#include <limits>

#include <Eigen/Core>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define RANKSLAM_GEOMETRY_HAVE_VNNI_PASS 1
#endif

namespace rankslam::geometry {

namespace {

using vector::Best;
using vector::update;

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

#ifdef RANKSLAM_GEOMETRY_HAVE_VNNI_PASS
#define RANKSLAM_VNNI_TARGET __attribute__((target("avx2,fma,avx512f,avx512vl,avx512vnni")))

// The 8 int32 lanes of each of s[0..7], summed, as 8 floats.
RANKSLAM_VNNI_TARGET inline __m256 lane_sums(const __m256i* s) {
  const __m256i s0123 = _mm256_hadd_epi32(_mm256_hadd_epi32(s[0], s[1]), _mm256_hadd_epi32(s[2], s[3]));
  const __m256i s4567 = _mm256_hadd_epi32(_mm256_hadd_epi32(s[4], s[5]), _mm256_hadd_epi32(s[6], s[7]));
  return _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_permute2x128_si256(s0123, s4567, 0x20),
                                             _mm256_permute2x128_si256(s0123, s4567, 0x31)));
}

// Approximate dot products of 3 rows of A (unsigned bytes) with `columns` rows of B (signed
// bytes; a multiple of 8), rows of `dimension` bytes (a multiple of 32), scaled back to float
// into out[r · stride + j]. 3 × 8 blocks: 24 accumulators, 3 rows of A and one of B in 28 of
// AVX-512's 32 registers. The sums are exact (at most 512 · 255 · 127 < 2^24).
RANKSLAM_VNNI_TARGET void approximate_rows_vnni(const std::uint8_t* a, const float* inverse_a,
                                                const std::int8_t* b, const float* inverse_b,
                                                int columns, int dimension, float* out, int stride) {
  const std::uint8_t* a1 = a + dimension;
  const std::uint8_t* a2 = a1 + dimension;
  for (int j = 0; j < columns; j += 8) {
    const std::int8_t* b0 = b + static_cast<std::ptrdiff_t>(j) * dimension;
    __m256i s[24];
    for (__m256i& sum : s) sum = _mm256_setzero_si256();
    for (int k = 0; k < dimension; k += 32) {
      const __m256i x0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a + k));
      const __m256i x1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a1 + k));
      const __m256i x2 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a2 + k));
      for (int c = 0; c < 8; ++c) {
        const __m256i y = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b0 + static_cast<std::ptrdiff_t>(c) * dimension + k));
        s[c] = _mm256_dpbusd_epi32(s[c], x0, y);
        s[8 + c] = _mm256_dpbusd_epi32(s[8 + c], x1, y);
        s[16 + c] = _mm256_dpbusd_epi32(s[16 + c], x2, y);
      }
    }
    const __m256 scale_b = _mm256_loadu_ps(inverse_b + j);
    for (int r = 0; r < 3; ++r) {
      _mm256_storeu_ps(out + static_cast<std::ptrdiff_t>(r) * stride + j,
                       _mm256_mul_ps(_mm256_mul_ps(lane_sums(s + 8 * r), _mm256_set1_ps(inverse_a[r])), scale_b));
    }
  }
}
#undef RANKSLAM_VNNI_TARGET

// One descriptor as bytes for the 8-bit pass, 8 values at a time (AVX2): q = ⌊v · scale + ½⌋
// with scale = levels / largest (levels ≤ 255), so |v − q / scale| ≤ (½ + 2⁻¹⁵) / scale, float
// rounding included; `padded` − `dimension` zero bytes after. Also 1 / scale, the L1 norm of the
// bytes scaled back and the L2 norm of the floats, both rounded up. False for a negative or
// non-finite value.
__attribute__((target("avx2"))) bool quantise(const float* row, int dimension, int padded, int levels,
                                              std::uint8_t* out, float& inverse, float& l1, float& norm) {
  const int vector_end = dimension - dimension % 8;
  const __m256 zero = _mm256_setzero_ps();
  const __m256 finite = _mm256_set1_ps(std::numeric_limits<float>::max());
  __m256 largest = zero;
  __m256 squares = zero;
  __m256 valid = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  for (int k = 0; k < vector_end; k += 8) {
    const __m256 v = _mm256_loadu_ps(row + k);
    valid = _mm256_and_ps(valid, _mm256_and_ps(_mm256_cmp_ps(v, zero, _CMP_GE_OQ), _mm256_cmp_ps(v, finite, _CMP_LE_OQ)));
    largest = _mm256_max_ps(largest, v);
    squares = _mm256_add_ps(squares, _mm256_mul_ps(v, v));
  }
  if (_mm256_movemask_ps(valid) != 0xff) return false;
  alignas(32) float lanes[8];
  _mm256_store_ps(lanes, largest);
  float top = 0.0F;
  for (const float v : lanes) top = std::max(top, v);
  _mm256_store_ps(lanes, squares);
  float square_sum = 0.0F;
  for (const float v : lanes) square_sum += v;
  for (int k = vector_end; k < dimension; ++k) {
    const float v = row[k];
    if (!(v >= 0.0F) || !(v <= std::numeric_limits<float>::max())) return false;
    top = std::max(top, v);
    square_sum += v * v;
  }
  const float scale = top > 0.0F ? static_cast<float>(levels) / top : 1.0F;
  const __m256 scale_v = _mm256_set1_ps(scale);
  const __m256 half = _mm256_set1_ps(0.5F);
  const __m256i most = _mm256_set1_epi32(levels);
  __m256i sums = _mm256_setzero_si256();
  int k = 0;
  for (; k < vector_end; k += 8) {
    const __m256i q = _mm256_min_epi32(
        _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(_mm256_loadu_ps(row + k), scale_v), half)), most);
    sums = _mm256_add_epi32(sums, q);
    // 8 values ≤ 255 to 8 bytes: 32 → 16 bits (within 128-bit halves), then 16 → 8 bits.
    const __m128i words = _mm_packus_epi32(_mm256_castsi256_si128(q), _mm256_extracti128_si256(q, 1));
    _mm_storel_epi64(reinterpret_cast<__m128i*>(out + k), _mm_packus_epi16(words, words));
  }
  alignas(32) std::int32_t counts[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(counts), sums);
  long sum = 0;
  for (const std::int32_t c : counts) sum += c;
  for (; k < dimension; ++k) {
    const int q = std::min(static_cast<int>(row[k] * scale + 0.5F), levels);
    out[k] = static_cast<std::uint8_t>(q);
    sum += q;
  }
  std::fill(out + dimension, out + padded, std::uint8_t{0});
  inverse = 1.0F / scale;
  l1 = static_cast<float>(static_cast<double>(sum) / static_cast<double>(scale) * (1.0 + 1e-6));
  // The float sum of squares is within dimension · 2⁻²⁴ of itself.
  norm = std::sqrt(square_sum) * 1.001F;
  return true;
}

// The bound ε on |float dot − approximate dot| of row i of A with each row j of B: with
// v = q / scale + e, |e| ≤ 0.50004 / scale, a·b − â·b̂ = â·e_b + e_a·b̂ + e_a·e_b, so
//   ε_ij = (0.50004·L1(â_i) + 0.2501·dim/scale_a,i) / scale_b,j + 0.50004/scale_a,i · L1(b̂_j)
//          + 2(dim + 8)·2⁻²³·‖a_i‖·‖b_j‖ + 10⁻⁶,
// the last terms for the float sums' own rounding (at most dim + 8 roundings of a sum no larger
// than ‖a‖·‖b‖, taken twice over) and the approximate values' (a few ulp). Per row i the
// coefficients of B's 1/scale, L1 norm and L2 norm, 10⁻⁴ larger for the rounding of ε itself.
struct RowBound {
  float of_inverse;
  float of_l1;
  float of_norm;
};

// B's per-row terms of ε: 1/scale, L1 norm, L2 norm (padding rows zero).
struct ColumnTerms {
  const float* inverse;
  const float* l1;
  const float* norm;
};

// ε of one row of A with the 8 rows of B from j on.
__attribute__((target("avx2,fma"), always_inline)) inline __m256 pair_bounds(const RowBound& bound,
                                                                            const ColumnTerms& b, int j) {
  return _mm256_fmadd_ps(_mm256_set1_ps(bound.of_inverse), _mm256_loadu_ps(b.inverse + j),
                         _mm256_fmadd_ps(_mm256_set1_ps(bound.of_l1), _mm256_loadu_ps(b.l1 + j),
                                         _mm256_fmadd_ps(_mm256_set1_ps(bound.of_norm), _mm256_loadu_ps(b.norm + j),
                                                         _mm256_set1_ps(1e-6F))));
}

// Per j < count (a multiple of 8) of one row: the approximate value's lower bound s' − ε;
// returns the largest and raises column_lower[j] to each.
__attribute__((target("avx2,fma"))) float row_lower_bounds(const float* approximate, const RowBound& bound,
                                                           const ColumnTerms& terms, int count, int valid,
                                                           float* column_lower) {
  const __m256 lane = _mm256_setr_ps(0.0F, 1.0F, 2.0F, 3.0F, 4.0F, 5.0F, 6.0F, 7.0F);
  const __m256 lowest = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
  __m256 best = lowest;
  for (int j = 0; j < count; j += 8) {
    __m256 lower = _mm256_sub_ps(_mm256_loadu_ps(approximate + j), pair_bounds(bound, terms, j));
    // Columns past the valid ones (padding) bound nothing.
    lower = _mm256_blendv_ps(lowest, lower, _mm256_cmp_ps(lane, _mm256_set1_ps(static_cast<float>(valid - j)), _CMP_LT_OQ));
    best = _mm256_max_ps(best, lower);
    _mm256_storeu_ps(column_lower + j, _mm256_max_ps(_mm256_loadu_ps(column_lower + j), lower));
  }
  const __m128 half = _mm_max_ps(_mm256_castps256_ps128(best), _mm256_extractf128_ps(best, 1));
  const __m128 quarter = _mm_max_ps(half, _mm_movehl_ps(half, half));
  return _mm_cvtss_f32(_mm_max_ss(quarter, _mm_shuffle_ps(quarter, quarter, 0x55)));
}

// The j < valid (count: valid rounded up to 8) whose upper bound s' + ε reaches limits[j] (or
// limits[0] for every j when `one_limit`), ascending, into `out`; returns how many.
__attribute__((target("avx2,fma"))) int reaching(const float* approximate, const RowBound& bound,
                                                 const ColumnTerms& terms, const float* limits,
                                                 bool one_limit, int count, int valid, int* out) {
  const __m256 single = _mm256_set1_ps(limits[0]);
  int found = 0;
  for (int j = 0; j < count; j += 8) {
    const __m256 upper = _mm256_add_ps(_mm256_loadu_ps(approximate + j), pair_bounds(bound, terms, j));
    const __m256 limit = one_limit ? single : _mm256_loadu_ps(limits + j);
    auto mask = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(upper, limit, _CMP_GE_OQ)));
    while (mask != 0) {
      const int index = j + __builtin_ctz(mask);
      mask &= mask - 1;
      if (index < valid) out[found++] = index;
    }
  }
  return found;
}
#endif

// Rows of A go to the float kernels in chunks of this many (a multiple of their 4-row blocks);
// the chunks also decide how vector::scan_dot_products sums each pair (sums_in_sequence).
constexpr int kRowsPerChunk = 32;

#ifdef RANKSLAM_GEOMETRY_HAVE_VNNI_PASS
// True where vector::scan_dot_products sums pair (i, j) in sequence: a row in a whole 4-row block of
// its chunk, against one of the last nb mod 3 columns, which its 4 × 3 blocks leave over.
bool sums_in_sequence(int i, int na, int j, int nb) {
  const int chunk_start = i / kRowsPerChunk * kRowsPerChunk;
  const int chunk_rows = std::min(kRowsPerChunk, na - chunk_start);
  return i - chunk_start < chunk_rows - chunk_rows % 4 && j >= nb - nb % 3;
}
#endif

}  // namespace

bool DescriptorMatcher::cpu_has_vnni() {
#ifdef RANKSLAM_GEOMETRY_HAVE_VNNI_PASS
  // Its candidates' exact values are the vector kernel's sums.
  static const bool has = parallel::vector_kernels_enabled() && __builtin_cpu_supports("avx2") &&
                          __builtin_cpu_supports("fma") && __builtin_cpu_supports("avx512f") &&
                          __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512vnni");
  return has;
#else
  return false;
#endif
}

bool DescriptorMatcher::has_vector_kernel() { return parallel::vector_kernels_enabled(); }

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
  use_vector_ = kernel != Kernel::kPortable && has_vector_kernel();
  // Up to 512 values the 8-bit sums stay below 2^24, exact in float.
  constexpr int kMaxQuantisedDimension = 512;
  use_vnni_ = kernel == Kernel::kBest && cpu_has_vnni() && dimension <= kMaxQuantisedDimension;
  if (use_vnni_) {
    quantised_dimension_ = (dimension + 31) / 32 * 32;
    const auto rows_a = static_cast<std::size_t>((max_descriptors + 2) / 3 * 3);
    const auto rows_b = static_cast<std::size_t>((max_descriptors + 7) / 8 * 8);
    approximate_stride_ = static_cast<int>(rows_b);
    const auto row = static_cast<std::size_t>(quantised_dimension_);
    quantised_a_.assign(rows_a * row, 0);
    quantised_b_.assign(rows_b * row, 0);
    inverse_scale_a_.assign(rows_a, 0.0F);
    inverse_scale_b_.assign(rows_b, 0.0F);
    l1_a_.assign(rows_a, 0.0F);
    l1_b_.assign(rows_b, 0.0F);
    norm_a_.assign(rows_a, 0.0F);
    norm_b_.assign(rows_b, 0.0F);
    approximate_.assign(rows_a * rows_b, 0.0F);
    column_lower_.assign(rows_b * blocks, 0.0F);
    candidates_.assign(rows_b * blocks, 0);
  }
  capacity_ = max_descriptors;
  return {};
}

int DescriptorMatcher::match(const float* a, int count_a, const float* b, int count_b,
                             std::span<DescriptorMatch> out) {
  if (!configured() || count_a > capacity_ || count_b > capacity_ || count_a < 0 || count_b < 0) {
    return -1;
  }
  if (count_a == 0 || count_b == 0) return 0;
  // Each row's best column into best_of_a_ / arg_of_a_, each column's best row into the first
  // count_b entries of best_of_b_ / arg_of_b_; ties to the lower index.
  if (!use_vnni_ || !match_8bit(a, count_a, b, count_b)) match_float(a, count_a, b, count_b);
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

void DescriptorMatcher::match_float(const float* a, int count_a, const float* b, int count_b) {
  // A's rows in chunks to whichever thread asks, each thread with its own best of B's rows over
  // the rows it scanned (which come to it in increasing order, so ties within a thread keep the
  // lower row); the threads' bests are then merged, ties again to the lower row. Chunk edges fall
  // on multiples of the kernels' 4 rows, so every dot product is summed as in one pass.
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
    if (use_vector_) {
      vector::scan_dot_products(rows_of_a, end - first, b, count_b, dimension_, best);
    } else {
      scan_portable(rows_of_a, end - first, b, count_b, dimension_, best);
    }
  };
  parallel::for_chunks(team_, count_a, kRowsPerChunk, scan_rows);
  merge_column_bests(count_b);
}

void DescriptorMatcher::merge_column_bests(int count_b) {
  const int threads = parallel::team_size(team_);
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
}

bool DescriptorMatcher::match_8bit(const float* a, int count_a, const float* b, int count_b) {
#ifdef RANKSLAM_GEOMETRY_HAVE_VNNI_PASS
  const int dim = dimension_;
  const int padded = quantised_dimension_;
  const int stride = approximate_stride_;
  const int columns = (count_b + 7) / 8 * 8;
  // Both sides as bytes, A unsigned (0…255) and B signed (0…127), as vpdpbusd takes them. A row
  // that cannot be (a negative value) gets a zero scale; then the float kernel does the match.
  constexpr int kRowsPerQuantiseChunk = 64;
  parallel::for_chunks(team_, std::max(count_a, count_b), kRowsPerQuantiseChunk, [&](int first, int end, int /*thread*/) {
    for (int i = first; i < end; ++i) {
      const auto r = static_cast<std::size_t>(i);
      const auto at = static_cast<std::ptrdiff_t>(i) * padded;
      if (i < count_a &&
          !quantise(a + static_cast<std::ptrdiff_t>(i) * dim, dim, padded, 255, quantised_a_.data() + at,
                    inverse_scale_a_[r], l1_a_[r], norm_a_[r])) {
        inverse_scale_a_[r] = 0.0F;
      }
      if (i < count_b &&
          !quantise(b + static_cast<std::ptrdiff_t>(i) * dim, dim, padded, 127,
                    reinterpret_cast<std::uint8_t*>(quantised_b_.data() + at),
                    inverse_scale_b_[r], l1_b_[r], norm_b_[r])) {
        inverse_scale_b_[r] = 0.0F;
      }
    }
  });
  for (int i = 0; i < count_a; ++i) {
    if (!(inverse_scale_a_[static_cast<std::size_t>(i)] > 0.0F)) return false;
  }
  for (int j = 0; j < count_b; ++j) {
    if (!(inverse_scale_b_[static_cast<std::size_t>(j)] > 0.0F)) return false;
  }
  // Padding rows: zero bytes, zero scale and norms (their approximate values are 0 and never
  // taken).
  const int rows_a = (count_a + 2) / 3 * 3;
  for (int i = count_a; i < rows_a; ++i) {
    std::fill_n(quantised_a_.begin() + static_cast<std::ptrdiff_t>(i) * padded, padded, std::uint8_t{0});
    inverse_scale_a_[static_cast<std::size_t>(i)] = 0.0F;
  }
  for (int j = count_b; j < columns; ++j) {
    const auto r = static_cast<std::size_t>(j);
    std::fill_n(quantised_b_.begin() + static_cast<std::ptrdiff_t>(j) * padded, padded, std::int8_t{0});
    inverse_scale_b_[r] = l1_b_[r] = norm_b_[r] = 0.0F;
  }
  const ColumnTerms terms{inverse_scale_b_.data(), l1_b_.data(), norm_b_.data()};
  const auto bound_of_row = [&](int i) {
    const auto r = static_cast<std::size_t>(i);
    constexpr float kRoundUp = 1.0001F;
    const auto d = static_cast<float>(dim);
    return RowBound{(0.50004F * l1_a_[r] + 0.2501F * d * inverse_scale_a_[r]) * kRoundUp,
                    0.50004F * inverse_scale_a_[r] * kRoundUp,
                    2.0F * (d + 8.0F) * std::ldexp(1.0F, -23) * norm_a_[r] * kRoundUp};
  };
  // Exact values, summed as the float kernel sums each pair.
  const auto exact = [&](int i, int j) {
    const float* x = a + static_cast<std::ptrdiff_t>(i) * dim;
    const float* y = b + static_cast<std::ptrdiff_t>(j) * dim;
    return sums_in_sequence(i, count_a, j, count_b) ? vector::dot_in_sequence(x, y, dim) : vector::dot_in_lanes(x, y, dim);
  };
  constexpr float kLowest = -std::numeric_limits<float>::infinity();
  const int threads = parallel::team_size(team_);
  for (int thread = 0; thread < threads; ++thread) {
    std::fill_n(column_lower_.begin() + static_cast<std::ptrdiff_t>(thread) * stride, columns, kLowest);
  }
  // Rows in chunks of whole 3-row blocks: the approximate values, then each row's best among
  // the columns whose upper bound reaches the row's largest lower bound (every column that can
  // be its best), and the columns' largest lower bounds over the chunk's rows.
  constexpr int kRowsPerVnniChunk = 24;
  parallel::for_chunks(team_, count_a, kRowsPerVnniChunk, [&](int first, int end, int thread) {
    for (int i = first; i < end; i += 3) {
      approximate_rows_vnni(quantised_a_.data() + static_cast<std::ptrdiff_t>(i) * padded,
                            inverse_scale_a_.data() + i, quantised_b_.data(), inverse_scale_b_.data(),
                            columns, padded, approximate_.data() + static_cast<std::ptrdiff_t>(i) * stride, stride);
    }
    float* column_lower = column_lower_.data() + static_cast<std::ptrdiff_t>(thread) * stride;
    int* candidates = candidates_.data() + static_cast<std::ptrdiff_t>(thread) * stride;
    for (int i = first; i < end; ++i) {
      const float* row = approximate_.data() + static_cast<std::ptrdiff_t>(i) * stride;
      const RowBound bound = bound_of_row(i);
      const float row_lower = row_lower_bounds(row, bound, terms, columns, count_b, column_lower);
      const int found = reaching(row, bound, terms, &row_lower, true, columns, count_b, candidates);
      float best = kLowest;
      int arg = -1;
      for (int c = 0; c < found; ++c) {
        const int j = candidates[c];
        const float similarity = exact(i, j);
        if (similarity > best) {
          best = similarity;
          arg = j;
        }
      }
      best_of_a_[static_cast<std::size_t>(i)] = best;
      arg_of_a_[static_cast<std::size_t>(i)] = arg;
    }
  });
  for (int thread = 1; thread < threads; ++thread) {
    const float* other = column_lower_.data() + static_cast<std::ptrdiff_t>(thread) * stride;
    for (int j = 0; j < columns; ++j) {
      column_lower_[static_cast<std::size_t>(j)] = std::max(column_lower_[static_cast<std::size_t>(j)], other[j]);
    }
  }
  // Each column's best among the rows whose upper bound reaches the column's largest lower
  // bound: row by row, each thread keeping its own bests of the columns (its rows come to it in
  // increasing order, so its ties keep the lower row), merged as the float kernels' are.
  for (int thread = 0; thread < threads; ++thread) {
    const auto b_offset = static_cast<std::ptrdiff_t>(thread) * capacity_;
    std::fill_n(best_of_b_.begin() + b_offset, count_b, kLowest);
    std::fill_n(arg_of_b_.begin() + b_offset, count_b, -1);
  }
  parallel::for_chunks(team_, count_a, kRowsPerVnniChunk, [&](int first, int end, int thread) {
    float* best = best_of_b_.data() + static_cast<std::ptrdiff_t>(thread) * capacity_;
    int* arg = arg_of_b_.data() + static_cast<std::ptrdiff_t>(thread) * capacity_;
    int* candidates = candidates_.data() + static_cast<std::ptrdiff_t>(thread) * stride;
    for (int i = first; i < end; ++i) {
      const float* row = approximate_.data() + static_cast<std::ptrdiff_t>(i) * stride;
      const int found = reaching(row, bound_of_row(i), terms, column_lower_.data(), false, columns,
                                 count_b, candidates);
      for (int c = 0; c < found; ++c) {
        const int j = candidates[c];
        const float similarity = exact(i, j);
        if (similarity > best[j]) {
          best[j] = similarity;
          arg[j] = i;
        }
      }
    }
  });
  merge_column_bests(count_b);
  return true;
#else
  (void)a;
  (void)count_a;
  (void)b;
  (void)count_b;
  return false;
#endif
}

namespace {

// The portable loop over targets [begin, end) of the planes, continuing the rows' and columns'
// nearest so far. x86-64's baseline has no POPCNT instruction, so a POPCNT clone is chosen at
// load time where the CPU has it. The build itself never targets the build machine's CPU: the
// binary must run on any x86-64, and on arm64, whose baseline has a popcount.
// ThreadSanitizer instruments the clone's load-time resolver, which then runs before its runtime
// is set up and crashes the process: a TSan build takes the baseline loop.
#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define RANKSLAM_NO_POPCNT_CLONE
#endif
#endif
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_THREAD__) && !defined(RANKSLAM_NO_POPCNT_CLONE)
__attribute__((target_clones("popcnt", "default")))
#endif
void hamming_portable(const std::uint64_t* source, int n_source, const std::uint64_t* planes, std::ptrdiff_t stride,
                      int begin, int end, std::int64_t* row_best, std::int64_t* row_arg, std::int64_t* col_best,
                      std::int64_t* col_arg) {
  for (int i = 0; i < n_source; ++i) {
    const std::uint64_t* a = source + 4 * static_cast<std::ptrdiff_t>(i);
    std::int64_t best = row_best[i];
    std::int64_t best_j = row_arg[i];
    for (int j = begin; j < end; ++j) {
      const std::uint64_t* b = planes + j;
      const std::int64_t distance = __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[stride]) +
                                    __builtin_popcountll(a[2] ^ b[2 * stride]) +
                                    __builtin_popcountll(a[3] ^ b[3 * stride]);
      if (distance < best) {
        best = distance;
        best_j = j;
      }
      if (distance < col_best[j]) {
        col_best[j] = distance;
        col_arg[j] = i;
      }
    }
    row_best[i] = best;
    row_arg[i] = best_j;
  }
}

}  // namespace

void HammingNearest::reserve(std::size_t max_descriptors, bool vector) {
  use_vector_ = vector && parallel::vector_kernels_enabled();
  const std::size_t padded = (max_descriptors + 7) / 8 * 8;
  source_words_.reserve(max_descriptors * 4);
  target_planes_.reserve(padded * 4);
  for (std::vector<std::int64_t>* v : {&row_best_, &row_arg_}) v->reserve(max_descriptors);
  for (std::vector<std::int64_t>* v : {&col_best_, &col_arg_}) v->reserve(padded);
}

void HammingNearest::scan(const cv::Mat& source, const cv::Mat& target) {
  constexpr std::int64_t kFar = std::numeric_limits<std::int64_t>::max();
  const int n_source = source.rows;
  const int n_target = target.rows;
  const int stride = (n_target + 7) / 8 * 8;
  source_words_.resize(static_cast<std::size_t>(n_source) * 4);
  for (int r = 0; r < n_source; ++r) std::memcpy(&source_words_[static_cast<std::size_t>(r) * 4], source.ptr(r), 32);
  target_planes_.resize(static_cast<std::size_t>(stride) * 4);
  for (int r = 0; r < n_target; ++r) {
    std::uint64_t words[4];
    std::memcpy(words, target.ptr(r), 32);
    for (int k = 0; k < 4; ++k) target_planes_[static_cast<std::size_t>(k * stride + r)] = words[k];
  }
  row_best_.assign(static_cast<std::size_t>(n_source), kFar);
  row_arg_.assign(static_cast<std::size_t>(n_source), static_cast<std::int64_t>(kNone));
  col_best_.assign(static_cast<std::size_t>(stride), kFar);
  col_arg_.assign(static_cast<std::size_t>(stride), static_cast<std::int64_t>(kNone));
  int done = 0;
  if (use_vector_ && n_source > 0) {
    done = vector::hamming_scan(source_words_.data(), n_source, target_planes_.data(), stride, n_target,
                                row_best_.data(), row_arg_.data(), col_best_.data(), col_arg_.data());
  }
  hamming_portable(source_words_.data(), n_source, target_planes_.data(), stride, done, n_target, row_best_.data(),
                   row_arg_.data(), col_best_.data(), col_arg_.data());
}

}  // namespace rankslam::geometry
