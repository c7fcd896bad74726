#include "rankslam/hal/associate.hpp"

#include <algorithm>
#include <cmath>

namespace rankslam::hal {
namespace {

struct Keyed {
  double stamp_s;
  std::size_t index;
};

/// Finite stamps sorted ascending, one entry per stamp value: the last in input order, which is
/// what associate.py's dict keeps.
std::vector<Keyed> sorted_unique(std::span<const double> stamps_s) {
  std::vector<Keyed> keyed;
  keyed.reserve(stamps_s.size());
  for (std::size_t i = 0; i < stamps_s.size(); ++i) {
    if (std::isfinite(stamps_s[i])) keyed.push_back({stamps_s[i], i});
  }
  std::stable_sort(keyed.begin(), keyed.end(),
                   [](const Keyed& a, const Keyed& b) { return a.stamp_s < b.stamp_s; });
  std::vector<Keyed> unique;
  unique.reserve(keyed.size());
  for (std::size_t i = 0; i < keyed.size(); ++i) {
    if (i + 1 < keyed.size() && keyed[i + 1].stamp_s == keyed[i].stamp_s) continue;
    unique.push_back(keyed[i]);
  }
  return unique;
}

struct Candidate {
  double difference_s;
  std::size_t first;   // position in the sorted first list
  std::size_t second;  // position in the sorted second list
};

}  // namespace

std::vector<StampMatch> associate_stamps(std::span<const double> first_stamps_s,
                                        std::span<const double> second_stamps_s,
                                        double max_difference_s) {
  if (!(max_difference_s > 0.0)) return {};  // also rejects NaN
  const std::vector<Keyed> first = sorted_unique(first_stamps_s);
  const std::vector<Keyed> second = sorted_unique(second_stamps_s);

  // Sliding window: every b with |a - b| < max_difference_s. Both tests use the same
  // floating-point differences as associate.py's abs(a - b) < max_difference, and the window's
  // lower end only moves forward because a increases.
  std::vector<Candidate> candidates;
  std::size_t window_begin = 0;
  for (std::size_t i = 0; i < first.size(); ++i) {
    const double a = first[i].stamp_s;
    while (window_begin < second.size() && a - second[window_begin].stamp_s >= max_difference_s) {
      ++window_begin;
    }
    for (std::size_t j = window_begin; j < second.size(); ++j) {
      const double b = second[j].stamp_s;
      if (b - a >= max_difference_s) break;
      const double difference = std::abs(a - b);
      if (difference < max_difference_s) candidates.push_back({difference, i, j});
    }
  }

  // associate.py sorts (difference, a, b) tuples; positions in the sorted lists order as the
  // stamps do, and stamps are unique, so this is the same order.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    if (x.difference_s != y.difference_s) return x.difference_s < y.difference_s;
    if (x.first != y.first) return x.first < y.first;
    return x.second < y.second;
  });

  std::vector<bool> first_used(first.size(), false);
  std::vector<bool> second_used(second.size(), false);
  std::vector<std::pair<std::size_t, std::size_t>> taken;  // sorted positions
  for (const Candidate& c : candidates) {
    if (first_used[c.first] || second_used[c.second]) continue;
    first_used[c.first] = true;
    second_used[c.second] = true;
    taken.emplace_back(c.first, c.second);
  }
  std::sort(taken.begin(), taken.end());

  std::vector<StampMatch> matches;
  matches.reserve(taken.size());
  for (const auto& [i, j] : taken) matches.push_back({first[i].index, second[j].index});
  return matches;
}

}  // namespace rankslam::hal
