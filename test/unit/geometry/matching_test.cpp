#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/geometry/matching.hpp"
#include "rankslam/geometry/shot.hpp"

namespace rankslam::geometry {
namespace {

std::vector<float> random_descriptors(int n, int dim, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  std::vector<float> d(static_cast<std::size_t>(n) * static_cast<std::size_t>(dim));
  for (int i = 0; i < n; ++i) {
    double norm = 0.0;
    for (int k = 0; k < dim; ++k) {
      // Sparse and non-negative, like SHOT histograms.
      const float v = u(rng) < 0.3F ? u(rng) : 0.0F;
      d[static_cast<std::size_t>(i * dim + k)] = v;
      norm += static_cast<double>(v) * static_cast<double>(v);
    }
    const auto inverse = static_cast<float>(1.0 / std::sqrt(std::max(norm, 1e-12)));
    for (int k = 0; k < dim; ++k) d[static_cast<std::size_t>(i * dim + k)] *= inverse;
  }
  return d;
}

// Mutual nearest neighbours by brute force in double, ties to the lower index.
std::vector<std::pair<int, int>> reference(const std::vector<float>& a, int na, const std::vector<float>& b, int nb, int dim) {
  std::vector<int> best_a(static_cast<std::size_t>(na), -1), best_b(static_cast<std::size_t>(nb), -1);
  std::vector<double> sa(static_cast<std::size_t>(na), -1e30), sb(static_cast<std::size_t>(nb), -1e30);
  for (int i = 0; i < na; ++i) {
    for (int j = 0; j < nb; ++j) {
      double s = 0.0;
      for (int k = 0; k < dim; ++k) {
        s += static_cast<double>(a[static_cast<std::size_t>(i * dim + k)]) * static_cast<double>(b[static_cast<std::size_t>(j * dim + k)]);
      }
      if (s > sa[static_cast<std::size_t>(i)]) { sa[static_cast<std::size_t>(i)] = s; best_a[static_cast<std::size_t>(i)] = j; }
      if (s > sb[static_cast<std::size_t>(j)]) { sb[static_cast<std::size_t>(j)] = s; best_b[static_cast<std::size_t>(j)] = i; }
    }
  }
  std::vector<std::pair<int, int>> out;
  for (int i = 0; i < na; ++i) {
    const int j = best_a[static_cast<std::size_t>(i)];
    if (j >= 0 && best_b[static_cast<std::size_t>(j)] == i) out.emplace_back(i, j);
  }
  return out;
}

class MatcherTest : public ::testing::TestWithParam<DescriptorMatcher::Kernel> {};

TEST_P(MatcherTest, MutualMatchesEqualBruteForce) {
  for (const auto& [na, nb] : {std::pair{400, 400}, std::pair{397, 13}, std::pair{1, 5}, std::pair{3, 2}}) {
    const auto a = random_descriptors(na, kShotSize, 1);
    auto b = random_descriptors(nb, kShotSize, 2);
    // Plant exact counterparts so that there are mutual matches to find.
    for (int j = 0; j < std::min(na, nb); j += 3) {
      std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(j) * kShotSize, kShotSize, b.begin() + static_cast<std::ptrdiff_t>(j) * kShotSize);
    }
    DescriptorMatcher matcher;
    ASSERT_EQ(matcher.configure(400, kShotSize, GetParam()), "");
    std::vector<DescriptorMatch> out(400);
    const int n = matcher.match(a.data(), na, b.data(), nb, out);
    const auto expected = reference(a, na, b, nb, kShotSize);
    ASSERT_EQ(n, static_cast<int>(expected.size())) << na << "x" << nb;
    for (int k = 0; k < n; ++k) {
      EXPECT_EQ(out[static_cast<std::size_t>(k)].a, expected[static_cast<std::size_t>(k)].first);
      EXPECT_EQ(out[static_cast<std::size_t>(k)].b, expected[static_cast<std::size_t>(k)].second);
      EXPECT_GE(out[static_cast<std::size_t>(k)].distance, 0.0F);
    }
  }
}

TEST_P(MatcherTest, OddDimensionsAndLimits) {
  const auto a = random_descriptors(9, 13, 3);
  const auto b = random_descriptors(11, 13, 4);
  DescriptorMatcher matcher;
  ASSERT_EQ(matcher.configure(11, 13, GetParam()), "");
  std::vector<DescriptorMatch> out(20);
  const int n = matcher.match(a.data(), 9, b.data(), 11, out);
  EXPECT_EQ(n, static_cast<int>(reference(a, 9, b, 11, 13).size()));
  EXPECT_EQ(matcher.match(a.data(), 12, b.data(), 11, out), -1);  // over capacity
  EXPECT_EQ(matcher.match(a.data(), 0, b.data(), 11, out), 0);
  std::vector<DescriptorMatch> one(1);
  EXPECT_LE(matcher.match(a.data(), 9, b.data(), 11, one), 1);
}

INSTANTIATE_TEST_SUITE_P(Kernels, MatcherTest,
                         ::testing::Values(DescriptorMatcher::Kernel::kBest, DescriptorMatcher::Kernel::kPortable));

TEST(Matcher, ConfigureRejectsBadSizes) {
  DescriptorMatcher matcher;
  EXPECT_FALSE(matcher.configure(0, 352).empty());
  EXPECT_FALSE(matcher.configure(10, 0).empty());
  EXPECT_FALSE(matcher.configured());
  std::vector<DescriptorMatch> out(1);
  const float x = 1.0F;
  EXPECT_EQ(matcher.match(&x, 1, &x, 1, out), -1);
}

}  // namespace
}  // namespace rankslam::geometry
