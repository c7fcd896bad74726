#include "rankslam/wide/vlad.hpp"

#include "rankslam/hal/regular_file.hpp"

#include <opencv2/core.hpp>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

// The built-in vocabulary's bytes, generated from deploy/vocabulary at configure time.
extern "C" const unsigned char rankslam_built_in_vocabulary[];
extern "C" const std::size_t rankslam_built_in_vocabulary_size;

namespace rankslam::wide {
namespace {

constexpr std::array<unsigned char, 8> kMagic{'R', 'S', 'V', 'O', 'C', 'A', 'B', '\n'};
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kHeaderBytes = kMagic.size() + 3 * 4;

std::uint32_t crc32_of(const unsigned char* data, std::size_t n) {
  return static_cast<std::uint32_t>(::crc32(0L, data, static_cast<uInt>(n)));
}

void put_u32(std::vector<char>& out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(value >> (8U * static_cast<unsigned>(i))));
}

std::uint32_t get_u32(const unsigned char* at) {
  return static_cast<std::uint32_t>(at[0]) | (static_cast<std::uint32_t>(at[1]) << 8U) |
         (static_cast<std::uint32_t>(at[2]) << 16U) | (static_cast<std::uint32_t>(at[3]) << 24U);
}

}  // namespace

Vocabulary::Vocabulary(cv::Mat centres) : centres_(std::move(centres)) {
  if (centres_.type() != CV_32F || centres_.cols != kDimension || centres_.rows < 1 || centres_.rows > kMaxWords) {
    throw std::invalid_argument("a vocabulary is 1 to " + std::to_string(kMaxWords) + " rows of " +
                                std::to_string(kDimension) + " floats");
  }
  if (!cv::checkRange(centres_)) throw std::invalid_argument("a vocabulary's centres must be finite");
  if (!centres_.isContinuous()) centres_ = centres_.clone();
}

Vocabulary Vocabulary::train(const cv::Mat& descriptors, int words, std::uint64_t seed) {
  if (descriptors.type() != CV_32F || descriptors.cols != kDimension) {
    throw std::invalid_argument("vocabulary training takes rows of 128 floats (SIFT descriptors)");
  }
  if (words < 1 || words > kMaxWords || descriptors.rows < words) {
    throw std::invalid_argument("vocabulary training needs 1 to " + std::to_string(kMaxWords) +
                                " words and at least as many descriptors (" + std::to_string(descriptors.rows) +
                                " for " + std::to_string(words) + ")");
  }
  cv::theRNG().state = seed == 0 ? 1 : seed;
  cv::Mat labels;
  cv::Mat centres;
  cv::kmeans(descriptors, words, labels, cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-3), 3,
             cv::KMEANS_PP_CENTERS, centres);
  return Vocabulary(centres);
}

const Vocabulary& Vocabulary::built_in() {
  if (rankslam_built_in_vocabulary_size == 0) {
    throw std::runtime_error("this program was built without a vocabulary (deploy/vocabulary/built-in.rsvoc)");
  }
  static const Vocabulary vocabulary = parse(
      std::span<const unsigned char>(rankslam_built_in_vocabulary, rankslam_built_in_vocabulary_size),
      "the built-in vocabulary");
  return vocabulary;
}

std::vector<char> Vocabulary::serialise() const {
  std::vector<char> out;
  out.reserve(kHeaderBytes + static_cast<std::size_t>(vlad_size()) * 4 + 4);
  for (const unsigned char c : kMagic) out.push_back(static_cast<char>(c));
  put_u32(out, kVersion);
  put_u32(out, static_cast<std::uint32_t>(words()));
  put_u32(out, kDimension);
  for (int r = 0; r < centres_.rows; ++r) {
    for (int c = 0; c < kDimension; ++c) put_u32(out, std::bit_cast<std::uint32_t>(centres_.at<float>(r, c)));
  }
  put_u32(out, crc32_of(reinterpret_cast<const unsigned char*>(out.data()), out.size()));
  return out;
}

Vocabulary Vocabulary::parse(std::span<const unsigned char> bytes, const std::string& name) {
  const auto fault = [&](const std::string& what) { return std::runtime_error(name + ": " + what); };
  if (bytes.size() < kHeaderBytes + 4 || !std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
    throw fault("not a rankslam vocabulary (no RSVOCAB header)");
  }
  const std::uint32_t version = get_u32(bytes.data() + kMagic.size());
  if (version != kVersion) {
    throw fault("vocabulary version " + std::to_string(version) + ", this program reads " + std::to_string(kVersion));
  }
  const std::uint32_t words = get_u32(bytes.data() + kMagic.size() + 4);
  const std::uint32_t dimension = get_u32(bytes.data() + kMagic.size() + 8);
  if (dimension != kDimension) throw fault("descriptor dimension " + std::to_string(dimension) + ", not 128");
  if (words < 1 || words > kMaxWords) throw fault("word count " + std::to_string(words) + " outside 1.." + std::to_string(kMaxWords));
  const std::size_t floats = static_cast<std::size_t>(words) * kDimension;
  const std::size_t expected = kHeaderBytes + floats * 4 + 4;
  if (bytes.size() != expected) {
    throw fault("size " + std::to_string(bytes.size()) + " bytes, " + std::to_string(words) + " words take " +
                std::to_string(expected) + " (truncated or extended)");
  }
  if (crc32_of(bytes.data(), expected - 4) != get_u32(bytes.data() + expected - 4)) {
    throw fault("checksum mismatch (the file is corrupt)");
  }
  cv::Mat centres(static_cast<int>(words), kDimension, CV_32F);
  const unsigned char* at = bytes.data() + kHeaderBytes;
  for (std::size_t i = 0; i < floats; ++i, at += 4) {
    const float value = std::bit_cast<float>(get_u32(at));
    if (!std::isfinite(value)) throw fault("centre value " + std::to_string(i) + " is not finite");
    centres.ptr<float>()[i] = value;
  }
  return Vocabulary(centres);
}

Vocabulary Vocabulary::load(const std::string& path) {
  std::vector<unsigned char> bytes;
  // kMaxWords centres with framing.
  const std::string error = hal::read_regular_file(path, kHeaderBytes + std::size_t{kMaxWords} * kDimension * 4 + 4, bytes);
  if (!error.empty()) throw std::runtime_error(error);
  return parse(bytes, path);
}

void encode_vlad(const Vocabulary& vocabulary, const cv::Mat& descriptors, std::span<float> out) {
  const int words = vocabulary.words();
  constexpr int d = Vocabulary::kDimension;
  if (static_cast<int>(out.size()) != vocabulary.vlad_size()) throw std::invalid_argument("VLAD output of the wrong size");
  if (!descriptors.empty() && (descriptors.type() != CV_32F || descriptors.cols != d)) {
    throw std::invalid_argument("VLAD takes rows of 128 floats (SIFT descriptors)");
  }
  std::fill(out.begin(), out.end(), 0.0F);
  const float* centres = vocabulary.centres().ptr<float>();
  for (int r = 0; r < descriptors.rows; ++r) {
    const float* x = descriptors.ptr<float>(r);
    int best = 0;
    float best_distance = std::numeric_limits<float>::max();
    for (int w = 0; w < words; ++w) {
      const float* c = centres + static_cast<std::ptrdiff_t>(w) * d;
      float distance = 0.0F;
      for (int j = 0; j < d; ++j) distance += (x[j] - c[j]) * (x[j] - c[j]);
      if (distance < best_distance) {
        best_distance = distance;
        best = w;
      }
    }
    float* acc = out.data() + static_cast<std::ptrdiff_t>(best) * d;
    const float* c = centres + static_cast<std::ptrdiff_t>(best) * d;
    for (int j = 0; j < d; ++j) acc[j] += x[j] - c[j];
  }
  for (float& v : out) v = std::copysign(std::sqrt(std::abs(v)), v);
  for (int w = 0; w < words; ++w) {
    float* block = out.data() + static_cast<std::ptrdiff_t>(w) * d;
    float norm = 0.0F;
    for (int j = 0; j < d; ++j) norm += block[j] * block[j];
    if (norm > 0.0F) {
      const float scale = 1.0F / std::sqrt(norm);
      for (int j = 0; j < d; ++j) block[j] *= scale;
    }
  }
  float norm = 0.0F;
  for (const float v : out) norm += v * v;
  if (norm > 0.0F) {
    const float scale = 1.0F / std::sqrt(norm);
    for (float& v : out) v *= scale;
  }
}

float vlad_similarity(std::span<const float> a, std::span<const float> b) {
  if (a.size() != b.size()) throw std::invalid_argument("VLAD vectors of different sizes");
  float dot = 0.0F;
  for (std::size_t i = 0; i < a.size(); ++i) dot += a[i] * b[i];
  return dot;
}

}  // namespace rankslam::wide
