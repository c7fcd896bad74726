#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/eval/associate.hpp"

namespace rankslam::eval {
namespace {

using Pairs = std::vector<std::pair<double, double>>;

/// The matched stamps, for readable comparisons.
Pairs matched_stamps(const std::vector<StampMatch>& matches, const std::vector<double>& first,
                     const std::vector<double>& second) {
  Pairs pairs;
  for (const StampMatch& m : matches)
    pairs.emplace_back(first[m.first_index], second[m.second_index]);
  return pairs;
}

/// associate.py written out literally: every pair, sorted, taken greedily. O(n^2), for checking.
Pairs associate_reference(const std::vector<double>& first, const std::vector<double>& second,
                          double max_difference_s) {
  const std::set<double> first_keys(first.begin(), first.end());
  const std::set<double> second_keys(second.begin(), second.end());
  std::vector<std::tuple<double, double, double>> candidates;
  for (const double a : first_keys) {
    for (const double b : second_keys) {
      if (std::abs(a - b) < max_difference_s) candidates.emplace_back(std::abs(a - b), a, b);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::set<double> first_free = first_keys;
  std::set<double> second_free = second_keys;
  Pairs matches;
  for (const auto& [difference, a, b] : candidates) {
    if (first_free.count(a) != 0 && second_free.count(b) != 0) {
      first_free.erase(a);
      second_free.erase(b);
      matches.emplace_back(a, b);
    }
  }
  std::sort(matches.begin(), matches.end());
  return matches;
}

TEST(Associate, MatchesWithinWindowAndSortsByFirstStamp) {
  const std::vector<double> first = {0.0, 0.1, 0.2, 0.3};
  const std::vector<double> second = {0.305, 0.005, 0.21};
  const auto matches = associate(first, second);
  EXPECT_EQ(matched_stamps(matches, first, second),
            (Pairs{{0.0, 0.005}, {0.2, 0.21}, {0.3, 0.305}}));
}

TEST(Associate, GapsWiderThanTheWindowLeaveStampsUnmatched) {
  const std::vector<double> first = {0.0, 0.1, 0.2, 1.0};
  const std::vector<double> second = {0.03, 0.11, 0.5, 0.979, 0.981};
  EXPECT_EQ(matched_stamps(associate(first, second), first, second),
            (Pairs{{0.1, 0.11}, {1.0, 0.981}}));
}

TEST(Associate, WindowIsStrict) {
  // Dyadic stamps: the differences are exact, so |a - b| == max_difference is not a match.
  const std::vector<double> first = {1.0, 2.0};
  const std::vector<double> second = {1.25, 2.125};
  EXPECT_EQ(matched_stamps(associate(first, second, 0.25), first, second), (Pairs{{2.0, 2.125}}));
}

TEST(Associate, GreedyByDifferenceNotNearestNeighbour) {
  // 0.010-0.006 (0.004) is taken first; 0.000 then gets 0.016 although 0.006 is nearer to it.
  const std::vector<double> first = {0.000, 0.010};
  const std::vector<double> second = {0.006, 0.016};
  EXPECT_EQ(matched_stamps(associate(first, second), first, second),
            (Pairs{{0.000, 0.016}, {0.010, 0.006}}));
}

TEST(Associate, EachStampIsUsedOnce) {
  // Three stamps compete for one: only the nearest gets it.
  const std::vector<double> first = {1.000, 1.001, 1.003};
  const std::vector<double> second = {1.0012};
  EXPECT_EQ(matched_stamps(associate(first, second), first, second), (Pairs{{1.001, 1.0012}}));
  // 1.000-1.001 is taken first, so 1.000 may not also take 1.002; 1.004 gets it instead.
  const std::vector<double> first_b = {1.000, 1.004};
  const std::vector<double> second_b = {1.001, 1.002};
  EXPECT_EQ(matched_stamps(associate(first_b, second_b), first_b, second_b),
            (Pairs{{1.000, 1.001}, {1.004, 1.002}}));
}

TEST(Associate, UnsortedInputGivesTheSameMatchesWithOriginalIndices) {
  const std::vector<double> first = {0.3, 0.0, 0.2, 0.1};
  const std::vector<double> second = {0.21, 0.305, 0.099, 0.005};
  const auto matches = associate(first, second);
  EXPECT_EQ(matched_stamps(matches, first, second),
            (Pairs{{0.0, 0.005}, {0.1, 0.099}, {0.2, 0.21}, {0.3, 0.305}}));
  ASSERT_EQ(matches.size(), 4U);
  EXPECT_EQ(matches[0].first_index, 1U);
  EXPECT_EQ(matches[0].second_index, 3U);
}

TEST(Associate, DuplicateStampsCountOnceAndTheLastOneIsUsed) {
  // associate.py keys a dict by stamp: duplicates collapse and the last line wins.
  const std::vector<double> first = {1.0, 2.0, 1.0, 1.0};
  const std::vector<double> second = {1.001, 1.002, 2.001, 2.001};
  const auto matches = associate(first, second);
  ASSERT_EQ(matches.size(), 2U);
  EXPECT_EQ(matches[0].first_index, 3U);
  EXPECT_EQ(matches[0].second_index, 0U);
  EXPECT_EQ(matches[1].first_index, 1U);
  EXPECT_EQ(matches[1].second_index, 3U);
}

TEST(Associate, NonFiniteStampsAndBadWindowsMatchNothing) {
  const std::vector<double> first = {std::nan(""), 1.0, std::numeric_limits<double>::infinity()};
  const std::vector<double> second = {1.0, std::nan("")};
  const auto matches = associate(first, second);
  ASSERT_EQ(matches.size(), 1U);
  EXPECT_EQ(matches[0].first_index, 1U);
  EXPECT_TRUE(associate(first, second, 0.0).empty());
  EXPECT_TRUE(associate(first, second, -1.0).empty());
  EXPECT_TRUE(associate(first, second, std::nan("")).empty());
  EXPECT_TRUE(associate(std::vector<double>{}, second).empty());
}

TEST(Associate, AgreesWithTheLiteralAlgorithmOnRandomStamps) {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 30; ++trial) {
    // Dense and jittered, with gaps and duplicates: many competing candidates.
    std::uniform_real_distribution<double> period_s(0.005, 0.05);
    std::uniform_real_distribution<double> jitter_s(-0.01, 0.01);
    std::bernoulli_distribution gap(0.05);
    std::bernoulli_distribution duplicate(0.03);
    auto make = [&](std::size_t count) {
      std::vector<double> stamps;
      double t = 100.0 + jitter_s(rng);
      const double period = period_s(rng);
      for (std::size_t i = 0; i < count; ++i) {
        t += period + (gap(rng) ? 0.2 : 0.0);
        // Round to microseconds, as files have them, so exact ties between candidates occur.
        stamps.push_back(std::round((t + jitter_s(rng)) * 1e6) / 1e6);
        if (duplicate(rng)) stamps.push_back(stamps.back());
      }
      std::shuffle(stamps.begin(), stamps.end(), rng);
      return stamps;
    };
    const std::vector<double> first = make(150);
    const std::vector<double> second = make(250);
    const double window_s = trial % 2 == 0 ? 0.02 : 0.05;
    EXPECT_EQ(matched_stamps(associate(first, second, window_s), first, second),
              associate_reference(first, second, window_s))
        << "trial " << trial;
  }
}

TEST(Associate, LongTrajectoriesAssociateCompletely) {
  // 20 000 ground-truth stamps at 100 Hz against 20 000 estimate stamps 3 ms later.
  std::vector<double> truth;
  std::vector<double> estimate;
  for (int k = 0; k < 20000; ++k) {
    truth.push_back(1305031098.0 + 0.01 * k);
    estimate.push_back(1305031098.003 + 0.01 * k);
  }
  const auto matches = associate(truth, estimate);
  ASSERT_EQ(matches.size(), 20000U);
  for (std::size_t k = 0; k < matches.size(); ++k) {
    ASSERT_EQ(matches[k].first_index, k);
    ASSERT_EQ(matches[k].second_index, k);
  }
}

}  // namespace
}  // namespace rankslam::eval
