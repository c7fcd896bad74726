#include "rankslam/slam/orb_frontend.hpp"

#include <gtest/gtest.h>

#include <random>

namespace rankslam::slam {
namespace {

cv::Mat random_descriptors(int rows, std::mt19937& rng) {
  cv::Mat descriptors(rows, 32, CV_8UC1);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 32; ++c) descriptors.at<unsigned char>(r, c) = static_cast<unsigned char>(byte(rng));
  }
  return descriptors;
}

TEST(MutualHammingMatcher, FindsPermutedCopiesWithSmallNoise) {
  std::mt19937 rng(7);
  const cv::Mat source = random_descriptors(200, rng);
  std::vector<int> permutation(200);
  std::iota(permutation.begin(), permutation.end(), 0);
  std::shuffle(permutation.begin(), permutation.end(), rng);
  cv::Mat target(200, 32, CV_8UC1);
  for (int i = 0; i < 200; ++i) {
    source.row(permutation[static_cast<std::size_t>(i)]).copyTo(target.row(i));
    target.at<unsigned char>(i, i % 32) ^= 0x05;  // two flipped bits
  }
  MutualHammingMatcher matcher;
  std::vector<FeatureMatch> matches;
  matcher.match(source, target, 64, matches);
  ASSERT_EQ(matches.size(), 200U);
  for (const auto& match : matches) {
    EXPECT_EQ(static_cast<int>(match.source), permutation[match.target]);
    EXPECT_EQ(match.distance, 2U);
  }
}

TEST(MutualHammingMatcher, DropsNonMutualAndDistantMatches) {
  cv::Mat source(2, 32, CV_8UC1, cv::Scalar(0));
  cv::Mat target(1, 32, CV_8UC1, cv::Scalar(0));
  source.at<unsigned char>(1, 0) = 0x01;  // both sources are nearest to the one target; only 0 is mutual
  MutualHammingMatcher matcher;
  std::vector<FeatureMatch> matches;
  matcher.match(source, target, 64, matches);
  ASSERT_EQ(matches.size(), 1U);
  EXPECT_EQ(matches[0].source, 0U);

  target.setTo(cv::Scalar(0xFF));  // 256 bits away from source 0
  matcher.match(source, target, 64, matches);
  EXPECT_TRUE(matches.empty());
  matcher.match(cv::Mat(0, 32, CV_8UC1), target, 64, matches);
  EXPECT_TRUE(matches.empty());
}

}  // namespace
}  // namespace rankslam::slam
