// wide::Vocabulary and VLAD: hand-computed encodings, training that finds known clusters, and a
// vocabulary file that round-trips and is refused, with its name, when damaged.
#include "rankslam/wide/vlad.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace rankslam::wide {
namespace {

constexpr int kD = Vocabulary::kDimension;

/// Two words: all zeros, and 100 in the first coordinate.
Vocabulary two_words() {
  cv::Mat centres(2, kD, CV_32F, cv::Scalar::all(0));
  centres.at<float>(1, 0) = 100.0F;
  return Vocabulary(centres);
}

std::string error_of(const std::vector<unsigned char>& bytes) {
  try {
    (void)Vocabulary::parse(bytes, "words.rsvoc");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return {};
}

TEST(Vlad, EncodesResidualsToTheNearestWordHandComputed) {
  const Vocabulary vocabulary = two_words();
  // Descriptor 0 (nearest word 0) has residual 9 in coordinate 1; descriptor 1 (nearest word 1,
  // at 90) has residual -10 in coordinate 0 and 16 in coordinate 2.
  cv::Mat descriptors(2, kD, CV_32F, cv::Scalar::all(0));
  descriptors.at<float>(0, 1) = 9.0F;
  descriptors.at<float>(1, 0) = 90.0F;
  descriptors.at<float>(1, 2) = 16.0F;
  std::vector<float> v(static_cast<std::size_t>(vocabulary.vlad_size()), 7.0F);
  encode_vlad(vocabulary, descriptors, v);
  // Signed square roots: word 0 (0, 3), word 1 (-√10, 4); each block to unit length, then the
  // whole: every non-zero becomes its block's share over √2.
  const float s = 1.0F / std::sqrt(2.0F);
  EXPECT_NEAR(v[1], s, 1e-6F);
  EXPECT_NEAR(v[kD + 0], -std::sqrt(10.0F) / std::sqrt(26.0F) * s, 1e-6F);
  EXPECT_NEAR(v[kD + 2], 4.0F / std::sqrt(26.0F) * s, 1e-6F);
  float others = 0.0F;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i != 1 && i != kD && i != kD + 2) others += std::abs(v[i]);
  }
  EXPECT_EQ(others, 0.0F);
  EXPECT_NEAR(vlad_similarity(v, v), 1.0F, 1e-6F);
}

TEST(Vlad, NoDescriptorsGiveTheZeroVector) {
  const Vocabulary vocabulary = two_words();
  std::vector<float> v(static_cast<std::size_t>(vocabulary.vlad_size()), 7.0F);
  encode_vlad(vocabulary, cv::Mat(), v);
  EXPECT_EQ(vlad_similarity(v, v), 0.0F);
  std::vector<float> wrong(3);
  EXPECT_THROW(encode_vlad(vocabulary, cv::Mat(), wrong), std::invalid_argument);
}

TEST(Vlad, SimilarDescriptorSetsScoreHigherThanOthers) {
  cv::RNG rng(3);
  cv::Mat centres(16, kD, CV_32F);
  rng.fill(centres, cv::RNG::UNIFORM, 0.0, 100.0);
  const Vocabulary vocabulary(centres);
  // Two sets of descriptors scattered about the words, and the first again with a little noise.
  cv::Mat a(200, kD, CV_32F), b(200, kD, CV_32F), noise(200, kD, CV_32F);
  rng.fill(a, cv::RNG::NORMAL, 0.0, 10.0);
  rng.fill(b, cv::RNG::NORMAL, 0.0, 10.0);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 2.0);
  for (int r = 0; r < a.rows; ++r) {
    a.row(r) += centres.row(r % 16);
    b.row(r) += centres.row(r % 16);
  }
  const cv::Mat a_again = a + noise;
  std::vector<float> va(static_cast<std::size_t>(vocabulary.vlad_size())), vb(va.size()), va2(va.size());
  encode_vlad(vocabulary, a, va);
  encode_vlad(vocabulary, b, vb);
  encode_vlad(vocabulary, a_again, va2);
  EXPECT_GT(vlad_similarity(va, va2), 0.8F);
  EXPECT_LT(vlad_similarity(va, vb), 0.3F);
}

TEST(Vocabulary, TrainingFindsKnownClusters) {
  cv::RNG rng(5);
  cv::Mat truth(4, kD, CV_32F, cv::Scalar::all(0));
  for (int w = 0; w < 4; ++w) truth.at<float>(w, 10 * w) = 200.0F;
  cv::Mat samples(400, kD, CV_32F);
  rng.fill(samples, cv::RNG::NORMAL, 0.0, 1.0);
  for (int r = 0; r < samples.rows; ++r) samples.row(r) += truth.row(r % 4);
  const Vocabulary vocabulary = Vocabulary::train(samples, 4, 1);
  ASSERT_EQ(vocabulary.words(), 4);
  for (int w = 0; w < 4; ++w) {
    double nearest = 1e9;
    for (int c = 0; c < 4; ++c) nearest = std::min(nearest, cv::norm(truth.row(w), vocabulary.centres().row(c)));
    // A mean of 100 unit-variance samples is √(128/100) ≈ 1.1 off in 128 dimensions; words lie 283 apart.
    EXPECT_LT(nearest, 2.0) << "cluster " << w;
  }
  EXPECT_THROW((void)Vocabulary::train(samples.rowRange(0, 3), 4, 1), std::invalid_argument);
}

TEST(Vocabulary, FileRoundTripsAndDamageIsRefusedByName) {
  const Vocabulary vocabulary = two_words();
  const std::vector<char> chars = vocabulary.serialise();
  const std::vector<unsigned char> bytes(chars.begin(), chars.end());
  const Vocabulary back = Vocabulary::parse(bytes, "words.rsvoc");
  EXPECT_EQ(cv::norm(back.centres(), vocabulary.centres(), cv::NORM_INF), 0.0);

  std::vector<unsigned char> truncated(bytes.begin(), bytes.end() - 5);
  EXPECT_NE(error_of(truncated).find("words.rsvoc: size"), std::string::npos) << error_of(truncated);
  std::vector<unsigned char> flipped = bytes;
  flipped[40] ^= 0x10U;
  EXPECT_NE(error_of(flipped).find("checksum"), std::string::npos) << error_of(flipped);
  std::vector<unsigned char> version = bytes;
  version[8] = 2;
  EXPECT_NE(error_of(version).find("version 2"), std::string::npos) << error_of(version);
  std::vector<unsigned char> magic = bytes;
  magic[0] = 'X';
  EXPECT_NE(error_of(magic).find("not a rankslam vocabulary"), std::string::npos) << error_of(magic);
  EXPECT_NE(error_of({}).find("words.rsvoc"), std::string::npos);

  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("rankslam_vlad_" + std::to_string(::getpid()) + ".rsvoc");
  std::ofstream(path, std::ios::binary).write(chars.data(), static_cast<std::streamsize>(chars.size()));
  EXPECT_EQ(Vocabulary::load(path.string()).words(), 2);
  std::filesystem::remove(path);
  try {
    (void)Vocabulary::load(path.string());
    ADD_FAILURE() << "a missing file loaded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST(Vocabulary, TheBuiltInOneLoads) {
  const Vocabulary& vocabulary = Vocabulary::built_in();
  EXPECT_GE(vocabulary.words(), 16);
  EXPECT_EQ(vocabulary.centres().cols, kD);
}

}  // namespace
}  // namespace rankslam::wide
