#pragma once

#include <cstdint>
#include <vector>

namespace rankslam::robust {

/// Scratch memory of the robust estimators (MSSE and RANSAC), sized once at set-up so that an
/// estimate allocates nothing. Hypotheses are streamed (only the best one is kept), so the memory
/// depends on the number of points only, not on the number of hypotheses.
///
/// A result's spans (inliers, order, mask, sorted residuals) point into this workspace: they stay
/// valid until the next estimate that uses it. One workspace per thread.
class RobustWorkspace {
 public:
  /// Pairs a residual with its point index for the one full sort per estimate.
  struct RankEntry {
    double key;
    int index;
  };

  RobustWorkspace() = default;
  explicit RobustWorkspace(int max_points) { reserve(max_points); }

  /// Set-up only (allocates): makes room for estimates over up to max_points points.
  void reserve(int max_points);

  [[nodiscard]] int capacity() const { return capacity_; }

  // Buffers of capacity() elements each, for the estimator templates.
  [[nodiscard]] double* scores() { return scores_.data(); }
  [[nodiscard]] double* sq_residuals() { return sq_residuals_.data(); }
  [[nodiscard]] double* inverse_variances() { return inverse_variances_.data(); }
  [[nodiscard]] int* order() { return order_.data(); }
  [[nodiscard]] std::uint8_t* mask() { return mask_.data(); }
  [[nodiscard]] RankEntry* rank_entries() { return rank_entries_.data(); }
  /// Second buffer of capacity() entries and the digit counts of the radix sort.
  [[nodiscard]] RankEntry* rank_scratch() { return rank_scratch_.data(); }
  [[nodiscard]] int* digit_counts() { return digit_counts_.data(); }
  /// Buckets of one radix-sort digit (11 bits: six passes cover a 64-bit key).
  static constexpr int kDigitBuckets = 1 << 11;

 private:
  int capacity_ = 0;
  std::vector<double> scores_;             // per-hypothesis selection scores (nth_element scratch)
  std::vector<double> sq_residuals_;       // chosen hypothesis' squared residuals, sorted ascending
  std::vector<double> inverse_variances_;  // 1/σ_i² when per-point noise scales are given
  std::vector<int> order_;                 // point indices in ascending residual order
  std::vector<std::uint8_t> mask_;         // 1 = inlier, per input point
  std::vector<RankEntry> rank_entries_;    // sort scratch
  std::vector<RankEntry> rank_scratch_;    // radix-sort ping-pong buffer
  std::vector<int> digit_counts_;          // radix-sort bucket counts
};

}  // namespace rankslam::robust
