#include "rankslam/robust/msse.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace rankslam::robust {

namespace {

template <class T>
int transition_of(std::span<const T> sorted_sq_residuals, int k0, int parameter_count,
                  double transition_factor, double* sigma_sq) {
  const auto n = static_cast<int>(sorted_sq_residuals.size());
  k0 = std::clamp(k0, parameter_count + 1, std::max(n, parameter_count + 1));
  const T* r2 = sorted_sq_residuals.data();
  double sum = 0.0;
  for (int i = 0; i < std::min(k0, n); ++i) sum += static_cast<double>(r2[i]);
  const double factor_sq = transition_factor * transition_factor;
  int j = std::min(k0, n);
  // Eq. 4.4 with squares on both sides: r_(j+1) ≤ T·σ_j ⇔ r_(j+1)² ≤ T²·Σ_{i≤j} r_(i)² / (j − p).
  while (j < n && static_cast<double>(r2[j]) * static_cast<double>(j - parameter_count) <= factor_sq * sum) {
    sum += static_cast<double>(r2[j]);
    ++j;
  }
  if (sigma_sq != nullptr) {
    *sigma_sq = j > parameter_count ? sum / static_cast<double>(j - parameter_count) : 0.0;
  }
  return j;
}

}  // namespace

int msse_transition(std::span<const double> sorted_sq_residuals, int k0, int parameter_count,
                    double transition_factor, double* sigma_sq) {
  return transition_of(sorted_sq_residuals, k0, parameter_count, transition_factor, sigma_sq);
}

int msse_transition(std::span<const float> sorted_sq_residuals, int k0, int parameter_count,
                    double transition_factor, double* sigma_sq) {
  return transition_of(sorted_sq_residuals, k0, parameter_count, transition_factor, sigma_sq);
}

int msse_first_order(double min_inlier_fraction, int n, int parameter_count, int sample_size) {
  // The small tolerance keeps ⌈0.2 · 500⌉ at 100 despite 0.2 · 500 = 100.00000000000001.
  const double k = std::ceil(min_inlier_fraction * static_cast<double>(n) - 1e-9);
  const int k0 = k > 0.0 ? static_cast<int>(std::min(k, 2.0e9)) : 0;
  return std::max({k0, parameter_count + 1, sample_size, 1});
}

namespace detail {

bool fill_inverse_variances(std::span<const double> point_sigma, int n,
                            RobustWorkspace& workspace) {
  double* inv = workspace.inverse_variances();
  for (int i = 0; i < n; ++i) {
    const double s = point_sigma[static_cast<std::size_t>(i)];
    if (!(s > 0.0) || !std::isfinite(s)) return false;
    inv[i] = 1.0 / (s * s);
    if (!std::isfinite(inv[i])) return false;
  }
  return true;
}

namespace {

// Below this many values std::sort is as fast as the radix passes.
constexpr int kRadixSortMinimum = 512;
constexpr int kDigitBits = 11;
static_assert(RobustWorkspace::kDigitBuckets == 1 << kDigitBits);

std::uint64_t key_bits(double key) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &key, sizeof bits);
  return bits;
}

// The order of the sorted residuals: by key, equal keys by index.
bool ranks_before(const RobustWorkspace::RankEntry& a, const RobustWorkspace::RankEntry& b) {
  return a.key < b.key || (a.key == b.key && a.index < b.index);
}

// Sorts entries by (key, index) for keys ≥ 0 (no NaN): the bits of a non-negative double order
// as the values do, so a stable least-significant-digit radix sort of entries that start in
// index order gives the same order as the comparison sort, in O(n) per 11-bit digit. Only the
// keys' upper 32 bits (sign, exponent and 20 mantissa bits) go through the radix passes, three
// instead of six: entries are then in (upper bits, index) order, and sorting the runs of equal
// upper bits on the whole key finishes the job (runs are few and short: the upper bits resolve
// a key to about 1e-6 of itself). Digits that every key shares (the exponent's high bits, often)
// are skipped.
void radix_sort(RobustWorkspace::RankEntry* entries, RobustWorkspace::RankEntry* scratch, int n,
                int* counts) {
  constexpr int kBuckets = RobustWorkspace::kDigitBuckets;
  constexpr int kFirstShift = 32;
  RobustWorkspace::RankEntry* from = entries;
  RobustWorkspace::RankEntry* to = scratch;
  for (int shift = kFirstShift; shift < 64; shift += kDigitBits) {
    std::fill(counts, counts + kBuckets, 0);
    for (int i = 0; i < n; ++i) ++counts[(key_bits(from[i].key) >> shift) & (kBuckets - 1)];
    if (counts[(key_bits(from[0].key) >> shift) & (kBuckets - 1)] == n) continue;  // one bucket
    int start = 0;
    for (int b = 0; b < kBuckets; ++b) {
      const int count = counts[b];
      counts[b] = start;
      start += count;
    }
    for (int i = 0; i < n; ++i) to[counts[(key_bits(from[i].key) >> shift) & (kBuckets - 1)]++] = from[i];
    std::swap(from, to);
  }
  if (from != entries) std::copy(from, from + n, entries);
  // Each run of equal upper bits by (key, index) (std::sort sorts short runs by insertion).
  for (int begin = 0; begin < n;) {
    const std::uint64_t upper = key_bits(entries[begin].key) >> kFirstShift;
    int end = begin + 1;
    while (end < n && key_bits(entries[end].key) >> kFirstShift == upper) ++end;
    if (end - begin > 1) std::sort(entries + begin, entries + end, ranks_before);
    begin = end;
  }
}

}  // namespace

void sort_residuals(RobustWorkspace& workspace, int n) {
  double* sq = workspace.sq_residuals();
  RobustWorkspace::RankEntry* entries = workspace.rank_entries();
  bool non_negative = true;
  for (int i = 0; i < n; ++i) {
    entries[i] = {sq[i], i};
    non_negative = non_negative && sq[i] >= 0.0;  // false for NaN too
  }
  if (n >= kRadixSortMinimum && non_negative) {
    // +0.0 and −0.0 compare equal but differ in bits; −0.0 (a negative zero product) becomes +0.0.
    for (int i = 0; i < n; ++i) entries[i].key += 0.0;
    radix_sort(entries, workspace.rank_scratch(), n, workspace.digit_counts());
  } else {
    std::sort(entries, entries + n, ranks_before);
  }
  int* order = workspace.order();
  for (int i = 0; i < n; ++i) {
    sq[i] = entries[i].key;
    order[i] = entries[i].index;
  }
}

int count_below(const double* values, int count, double bound) {
  // Four independent counters: about twice as fast as one, as the adds do not chain.
  int c0 = 0;
  int c1 = 0;
  int c2 = 0;
  int c3 = 0;
  int i = 0;
  for (; i + 4 <= count; i += 4) {
    c0 += values[i] < bound ? 1 : 0;
    c1 += values[i + 1] < bound ? 1 : 0;
    c2 += values[i + 2] < bound ? 1 : 0;
    c3 += values[i + 3] < bound ? 1 : 0;
  }
  for (; i < count; ++i) c0 += values[i] < bound ? 1 : 0;
  return c0 + c1 + c2 + c3;
}

int keep_below(double* values, int count, double bound) {
  int kept = 0;
  for (int i = 0; i < count; ++i) {
    const double value = values[i];
    values[kept] = value;  // written whatever it is: no branch on the comparison
    kept += value < bound ? 1 : 0;
  }
  return kept;
}

int count_at_most(const double* values, int count, double bound) {
  int inside = 0;
  for (int i = 0; i < count; ++i) inside += values[i] <= bound ? 1 : 0;
  return inside;
}

void scale_values(double* values, const double* factors, int count) {
  for (int i = 0; i < count; ++i) values[i] *= factors[i];
}

void fill_mask(RobustWorkspace& workspace, int n, int inliers) {
  std::uint8_t* mask = workspace.mask();
  std::fill(mask, mask + n, std::uint8_t{0});
  const int* order = workspace.order();
  for (int i = 0; i < inliers; ++i) mask[order[i]] = 1;
}

bool same_inlier_set(RobustWorkspace& workspace, int n, int inliers) {
  const std::uint8_t* mask = workspace.mask();
  int marked = 0;
  for (int i = 0; i < n; ++i) marked += mask[i];
  if (marked != inliers) return false;
  const int* order = workspace.order();
  for (int i = 0; i < inliers; ++i) {
    if (mask[order[i]] == 0) return false;
  }
  return true;
}

}  // namespace detail

}  // namespace rankslam::robust
