#pragma once

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace rankslam::wide {

/// A visual vocabulary for place recognition (ALGORITHMS.md §6.4): k-means centres ("words") of
/// SIFT descriptors. Trained by `rankslam vocabulary`; one is built into the program.
class Vocabulary {
 public:
  static constexpr int kDimension = 128;
  static constexpr int kMaxWords = 1024;

  Vocabulary() = default;
  /// `centres`: words × kDimension, CV_32F, finite, 1 ≤ words ≤ kMaxWords; else std::invalid_argument.
  explicit Vocabulary(cv::Mat centres);

  /// k-means over `descriptors` (rows, CV_32F × kDimension) with k-means++ seeding from `seed`;
  /// needs at least `words` rows.
  static Vocabulary train(const cv::Mat& descriptors, int words, std::uint64_t seed);
  /// The vocabulary built into the program (deploy/vocabulary, see its README).
  static const Vocabulary& built_in();

  /// The file's bytes: magic, version, words, dimension, the centres as little-endian floats,
  /// CRC32 of all before it.
  [[nodiscard]] std::vector<char> serialise() const;
  /// Reads what serialise() wrote; a wrong magic, version or size, a bad checksum or a
  /// non-finite centre throws std::runtime_error naming `name`.
  static Vocabulary parse(std::span<const unsigned char> bytes, const std::string& name);
  /// Reads the file at `path` (std::runtime_error naming it on any fault).
  static Vocabulary load(const std::string& path);

  [[nodiscard]] int words() const { return centres_.rows; }
  /// Floats in one VLAD vector.
  [[nodiscard]] int vlad_size() const { return centres_.rows * kDimension; }
  [[nodiscard]] const cv::Mat& centres() const { return centres_; }

 private:
  cv::Mat centres_;
};

/// VLAD of `descriptors` (rows of CV_32F × 128; Jégou et al. 2010): the residuals to each
/// descriptor's nearest word, summed per word, signed square root, each word's block
/// L2-normalised, then the whole (Arandjelović & Zisserman 2013) — so the dot product of two
/// vectors is their similarity, 1 for the same image. `out` has vlad_size() floats; all zero
/// when there are no descriptors. No allocation.
void encode_vlad(const Vocabulary& vocabulary, const cv::Mat& descriptors, std::span<float> out);

/// Dot product of two VLAD vectors of one size.
[[nodiscard]] float vlad_similarity(std::span<const float> a, std::span<const float> b);

}  // namespace rankslam::wide
