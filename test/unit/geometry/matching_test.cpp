#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "rankslam/geometry/matching.hpp"
#include "rankslam/geometry/shot.hpp"
#include "rankslam/parallel/cpu_features.hpp"
#include "rankslam/parallel/thread_team.hpp"

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
                         ::testing::Values(DescriptorMatcher::Kernel::kBest, DescriptorMatcher::Kernel::kFloat,
                                           DescriptorMatcher::Kernel::kPortable));

// Descriptors in near-identical pairs and near-ties, where an approximate pass could pick
// another best: b_j is a_j plus noise of `noise` relative size, renormalised, so many rows have
// several columns within a hair of their best.
std::vector<float> perturbed(const std::vector<float>& from, int n, int dim, float noise, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  std::vector<float> d(from.begin(), from.begin() + static_cast<std::ptrdiff_t>(n) * dim);
  for (int i = 0; i < n; ++i) {
    double norm = 0.0;
    for (int k = 0; k < dim; ++k) {
      float& v = d[static_cast<std::size_t>(i * dim + k)];
      v = std::max(0.0F, v + noise * (u(rng) - 0.5F));
      norm += static_cast<double>(v) * static_cast<double>(v);
    }
    const auto inverse = static_cast<float>(1.0 / std::sqrt(std::max(norm, 1e-12)));
    for (int k = 0; k < dim; ++k) d[static_cast<std::size_t>(i * dim + k)] *= inverse;
  }
  return d;
}

// The 8-bit pass only chooses which pairs the float kernel's sums are taken for: the matches and
// distances are the float kernel's, bit for bit, on one thread and on a team.
TEST(Matcher, TheEightBitPassGivesTheFloatKernelsMatches) {
  if (!DescriptorMatcher::cpu_has_vnni()) GTEST_SKIP() << "no AVX-512 VNNI: the 8-bit pass does not run here";
  parallel::ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  for (parallel::ThreadTeam* with : {static_cast<parallel::ThreadTeam*>(nullptr), &team}) {
    for (const auto& [na, nb] : {std::pair{400, 400}, std::pair{397, 13}, std::pair{31, 400}, std::pair{1, 5}, std::pair{5, 1}}) {
      for (const float noise : {0.0F, 1e-5F, 1e-3F, 0.03F}) {
        const auto a = random_descriptors(na, kShotSize, 11);
        // B's rows in threes, each three perturbed copies of one row of A: rows of A with
        // several columns closer to each other than the 8-bit values can tell apart.
        std::vector<float> sources(static_cast<std::size_t>(nb) * kShotSize);
        for (int j = 0; j < nb; ++j) {
          std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(j / 3 % na) * kShotSize, kShotSize,
                      sources.begin() + static_cast<std::ptrdiff_t>(j) * kShotSize);
        }
        auto b = perturbed(sources, nb, kShotSize, noise, 12);
        // Some exact duplicates among B's rows: ties for A's rows.
        for (int j = 1; j < nb; j += 7) {
          std::copy_n(b.begin() + static_cast<std::ptrdiff_t>(j - 1) * kShotSize, kShotSize, b.begin() + static_cast<std::ptrdiff_t>(j) * kShotSize);
        }
        DescriptorMatcher eight_bit;
        DescriptorMatcher float_only;
        ASSERT_EQ(eight_bit.configure(400, kShotSize, DescriptorMatcher::Kernel::kBest, with), "");
        ASSERT_EQ(float_only.configure(400, kShotSize, DescriptorMatcher::Kernel::kFloat, with), "");
        ASSERT_TRUE(eight_bit.uses_vnni());
        ASSERT_FALSE(float_only.uses_vnni());
        std::vector<DescriptorMatch> got(400), expected(400);
        const int n = eight_bit.match(a.data(), na, b.data(), nb, got);
        ASSERT_EQ(n, float_only.match(a.data(), na, b.data(), nb, expected)) << na << "x" << nb << " noise " << noise;
        EXPECT_GT(n, 0);
        for (int k = 0; k < n; ++k) {
          const auto m = static_cast<std::size_t>(k);
          ASSERT_EQ(got[m].a, expected[m].a) << na << "x" << nb << " noise " << noise << " match " << k;
          ASSERT_EQ(got[m].b, expected[m].b) << na << "x" << nb << " noise " << noise << " match " << k;
          ASSERT_EQ(got[m].distance, expected[m].distance);
        }
      }
    }
  }
}

// A negative value has no unsigned byte: such descriptors go to the float kernel, same matches.
TEST(Matcher, NegativeDescriptorsAreMatchedByTheFloatKernel) {
  auto a = random_descriptors(50, kShotSize, 21);
  auto b = random_descriptors(40, kShotSize, 22);
  a[5] = -a[5] - 0.01F;
  for (int j = 0; j < 40; j += 3) std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(j) * kShotSize, kShotSize, b.begin() + static_cast<std::ptrdiff_t>(j) * kShotSize);
  DescriptorMatcher matcher;
  ASSERT_EQ(matcher.configure(50, kShotSize), "");
  std::vector<DescriptorMatch> out(50);
  const int n = matcher.match(a.data(), 50, b.data(), 40, out);
  const auto expected = reference(a, 50, b, 40, kShotSize);
  ASSERT_EQ(n, static_cast<int>(expected.size()));
  for (int k = 0; k < n; ++k) {
    EXPECT_EQ(out[static_cast<std::size_t>(k)].a, expected[static_cast<std::size_t>(k)].first);
    EXPECT_EQ(out[static_cast<std::size_t>(k)].b, expected[static_cast<std::size_t>(k)].second);
  }
}

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

namespace rankslam::geometry {
namespace {

// 32-byte binary descriptors near a few bases (few bits flipped), so that many distances tie.
cv::Mat binary_descriptors(int n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> bit(0, 255);
  cv::Mat bases(4, 32, CV_8UC1);
  for (int r = 0; r < bases.rows; ++r) {
    for (int c = 0; c < 32; ++c) bases.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(byte(rng));
  }
  cv::Mat d(n, 32, CV_8UC1);
  for (int r = 0; r < n; ++r) {
    bases.row(r % bases.rows).copyTo(d.row(r));
    for (int flips = r % 5; flips > 0; --flips) {
      const int b = bit(rng);
      d.at<std::uint8_t>(r, b / 8) ^= static_cast<std::uint8_t>(1U << (b % 8));
    }
  }
  return d;
}

int hamming(const cv::Mat& a, int i, const cv::Mat& b, int j) {
  int distance = 0;
  for (int c = 0; c < 32; ++c) distance += std::popcount(static_cast<unsigned>(a.at<std::uint8_t>(i, c) ^ b.at<std::uint8_t>(j, c)));
  return distance;
}

// Every set size around the vector widths (2, 4 and 8 lanes) and a frame's, with the vector
// kernel and the portable loop: each source's nearest target and each target's nearest source
// and distance, ties to the lower index, as a brute-force scan finds them.
TEST(HammingNearest, BothWaysEqualBruteForceWithAndWithoutTheVectorKernel) {
  for (const bool vector : {true, false}) {
    HammingNearest nearest;
    nearest.reserve(1100, vector);
    EXPECT_EQ(nearest.uses_vector_kernel(), vector && parallel::vector_kernels_enabled());
    for (const auto& [n_source, n_target] : std::vector<std::pair<int, int>>{
             {1, 1}, {3, 7}, {13, 8}, {9, 9}, {40, 31}, {700, 1003}, {1003, 700}, {5, 1}}) {
      const cv::Mat source = binary_descriptors(n_source, 7U + static_cast<std::uint32_t>(n_source));
      const cv::Mat target = binary_descriptors(n_target, 11U + static_cast<std::uint32_t>(n_target));
      nearest.scan(source, target);
      std::vector<int> column_best(static_cast<std::size_t>(n_target), 1000);
      std::vector<int> column_source(static_cast<std::size_t>(n_target), -1);
      int wrong = 0;
      for (int i = 0; i < n_source; ++i) {
        int best = 1000;
        int best_j = -1;
        for (int j = 0; j < n_target; ++j) {
          const int distance = hamming(source, i, target, j);
          if (distance < best) {
            best = distance;
            best_j = j;
          }
          if (distance < column_best[static_cast<std::size_t>(j)]) {
            column_best[static_cast<std::size_t>(j)] = distance;
            column_source[static_cast<std::size_t>(j)] = i;
          }
        }
        wrong += nearest.nearest_target(i) != static_cast<std::uint32_t>(best_j) ? 1 : 0;
      }
      for (int j = 0; j < n_target; ++j) {
        wrong += nearest.nearest_source(j) != static_cast<std::uint32_t>(column_source[static_cast<std::size_t>(j)]) ? 1 : 0;
        wrong += nearest.source_distance(j) != static_cast<std::uint32_t>(column_best[static_cast<std::size_t>(j)]) ? 1 : 0;
      }
      EXPECT_EQ(wrong, 0) << n_source << " x " << n_target << (vector ? ", vector kernel" : ", portable");
    }
  }
}

}  // namespace
}  // namespace rankslam::geometry
