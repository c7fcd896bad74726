#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace rankslam::hal {

/// The TUM benchmark's association window (associate.py --max_difference).
inline constexpr double kDefaultMaxDifference_s = 0.02;

/// A pair of associated entries, as indices into the two inputs.
struct StampMatch {
  std::size_t first_index = 0;
  std::size_t second_index = 0;
};

/// Stamp association exactly as the TUM benchmark's associate.py (offset 0): every pair (a, b)
/// with |a - b| < max_difference_s is a candidate; candidates are taken greedily in order of
/// increasing |a - b| (ties by a, then b), each stamp at most once; the result is sorted by the
/// first stamp. As in associate.py, which keys a dict by stamp, entries with equal stamps count
/// once and the last of them in input order is the one used. Non-finite stamps are ignored.
/// Input order is free. Cost O(n log n + m log m) for m candidate pairs: candidates come from a
/// sliding window over the sorted stamps, not from all n^2 pairs.
[[nodiscard]] std::vector<StampMatch> associate_stamps(std::span<const double> first_stamps_s,
                                                      std::span<const double> second_stamps_s,
                                                      double max_difference_s = kDefaultMaxDifference_s);

}  // namespace rankslam::hal
