#include "rankslam/slam/orb_extractor.hpp"
#include "rankslam/core/units.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

namespace rankslam::slam {

namespace {

// Sixteen pixels at a time in GCC's portable vector type: SSE2 on x86-64, NEON on arm64, plain
// code elsewhere. No instruction-set intrinsics, so every target builds the same source.
using Bytes = std::uint8_t __attribute__((vector_size(16)));
constexpr int kLanes = 16;

inline Bytes load(const std::uint8_t* pixels) {
  Bytes v;
  std::memcpy(&v, pixels, sizeof v);
  return v;
}

inline Bytes broadcast(std::uint8_t value) {
  Bytes v;
  std::memset(&v, value, sizeof v);
  return v;
}

/// All ones where a > b, per lane.
inline Bytes greater(Bytes a, Bytes b) { return reinterpret_cast<Bytes>(a > b); }
inline Bytes lane_min(Bytes a, Bytes b) { return a < b ? a : b; }
inline Bytes lane_max(Bytes a, Bytes b) { return a > b ? a : b; }
/// max(a − b, 0) per lane.
inline Bytes positive_difference(Bytes a, Bytes b) { return a - lane_min(a, b); }

inline bool any_lane(Bytes v) {
  std::uint64_t words[2];
  std::memcpy(words, &v, sizeof v);
  return (words[0] | words[1]) != 0;
}

/// Per lane, the largest value v such that 9 contiguous entries of the 16-entry circle all reach
/// v: the maximum over the 16 arcs of the arc's minimum, found with minima over 2, 4 and 8
/// neighbours (64 minima instead of 128).
inline Bytes best_arc_minimum(const Bytes (&difference)[16]) {
  // Unrolled, the arrays live in registers instead of on the stack.
  Bytes over2[16];
  Bytes over4[16];
#pragma GCC unroll 16
  for (int k = 0; k < 16; ++k) over2[k] = lane_min(difference[k], difference[(k + 1) & 15]);
#pragma GCC unroll 16
  for (int k = 0; k < 16; ++k) over4[k] = lane_min(over2[k], over2[(k + 2) & 15]);
  Bytes best = broadcast(0);
#pragma GCC unroll 16
  for (int k = 0; k < 16; ++k) {
    best = lane_max(best, lane_min(lane_min(over4[k], over4[(k + 4) & 15]), difference[(k + 8) & 15]));
  }
  return best;
}

// The radius-3 Bresenham circle of FAST, clockwise from the top; 0, 4, 8 and 12 are the compass
// points.
constexpr int kCircle[16][2] = {{0, -3}, {1, -3}, {2, -2}, {3, -1}, {3, 0},  {3, 1},  {2, 2},  {1, 3},
                                {0, 3},  {-1, 3}, {-2, 2}, {-3, 1}, {-3, 0}, {-3, -1}, {-2, -2}, {-1, -3}};

/// SplitMix64 (Steele, Lea & Flood 2014): a fixed sequence on every platform, unlike the
/// distributions of <random>, whose algorithms the standard leaves to the library.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31U);
  }
  /// Uniform in (0, 1).
  double uniform() { return (static_cast<double>(next() >> 11U) + 0.5) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

// 7-tap Gaussian of σ = 2 in 1/256ths (exact: 17.96 33.56 48.84 55.32): the sum is 256, so
// 255 · 256 + 128 still fits 16 bits.
constexpr std::uint16_t kGauss0 = 56;
constexpr std::uint16_t kGauss1 = 49;
constexpr std::uint16_t kGauss2 = 33;
constexpr std::uint16_t kGauss3 = 18;
static_assert(kGauss0 + 2 * (kGauss1 + kGauss2 + kGauss3) == 256);

constexpr float kHarrisK = 0.04F;
constexpr int kHarrisHalfWindow = 3;

}  // namespace

const std::array<OrbExtractor::Test, OrbExtractor::kTests>& OrbExtractor::pattern() {
  static const std::array<Test, kTests> tests = [] {
    std::array<Test, kTests> drawn{};
    SplitMix64 random(kPatternSeed);
    constexpr double kSigma = 31.0 / 5.0;  // G II: variance S²/25 with S the patch size
    constexpr double kRadius = kPatchRadius;
    auto draw_point = [&](float& x, float& y) {
      double gx = 0.0;
      double gy = 0.0;
      do {
        // Box–Muller: two independent standard normals from two uniforms.
        const double r = std::sqrt(-2.0 * std::log(random.uniform()));
        const double phi = 2.0 * std::numbers::pi * random.uniform();
        gx = kSigma * r * std::cos(phi);
        gy = kSigma * r * std::sin(phi);
      } while (gx * gx + gy * gy > kRadius * kRadius);
      x = static_cast<float>(gx);
      y = static_cast<float>(gy);
    };
    for (Test& test : drawn) {
      do {
        draw_point(test.ax, test.ay);
        draw_point(test.bx, test.by);
      } while (std::lround(test.ax) == std::lround(test.bx) && std::lround(test.ay) == std::lround(test.by));
    }
    return drawn;
  }();
  return tests;
}

OrbExtractor::OrbExtractor(const OrbExtractorSettings& settings) : settings_(settings) {
  settings_.max_features = std::max(settings_.max_features, 1);
  settings_.levels = std::max(settings_.levels, 1);
  settings_.scale_factor = std::max(settings_.scale_factor, 1.01F);
  settings_.fast_threshold = std::clamp(settings_.fast_threshold, 1, 254);
  settings_.border_px = std::max(settings_.border_px, kPatchRadius + 1);
  for (int v = 0; v <= kPatchRadius; ++v) {
    const double half = kPatchRadius + 0.5;
    circle_half_width_[static_cast<std::size_t>(v)] =
        static_cast<int>(std::floor(std::sqrt(half * half - static_cast<double>(v * v))));
  }
  keypoints_.reserve(static_cast<std::size_t>(settings_.max_features));
  descriptor_storage_.create(settings_.max_features, kDescriptorBytes, CV_8UC1);
  set_up(settings.width, settings.height);
}

void OrbExtractor::set_fast_threshold(int threshold) { settings_.fast_threshold = std::clamp(threshold, 1, 254); }

void OrbExtractor::set_up(int width, int height) {
  settings_.width = width;
  settings_.height = height;
  levels_.clear();
  const int border = settings_.border_px;
  // Levels too small for one patch plus one 16-pixel FAST block are left out.
  for (int l = 0; l < settings_.levels; ++l) {
    const double scale = std::pow(static_cast<double>(settings_.scale_factor), l);
    Level level;
    level.width = static_cast<int>(std::lround(width / scale));
    level.height = static_cast<int>(std::lround(height / scale));
    if (level.width < 2 * border + kLanes || level.height < 2 * border + 1) break;
    levels_.push_back(std::move(level));
  }
  // ORB's budget per level: a geometric series in 1/scale_factor summing to max_features.
  const double factor = 1.0 / static_cast<double>(settings_.scale_factor);
  const auto n_levels = static_cast<int>(levels_.size());
  const double first =
      settings_.max_features * (1.0 - factor) / (1.0 - std::pow(factor, static_cast<double>(n_levels)));
  int assigned = 0;
  std::size_t rows = 0;
  for (int l = 0; l < n_levels; ++l) {
    Level& level = levels_[static_cast<std::size_t>(l)];
    level.budget = l + 1 < n_levels ? static_cast<int>(std::lround(first * std::pow(factor, l)))
                                    : std::max(settings_.max_features - assigned, 0);
    assigned += level.budget;
    level.scale_x = static_cast<float>(width) / static_cast<float>(level.width);
    level.scale_y = static_cast<float>(height) / static_cast<float>(level.height);
    level.offset = rows * static_cast<std::size_t>(width);
    rows += static_cast<std::size_t>(level.height);
    if (l == 0) continue;
    // Bilinear resampling tables from the level above, pixel centres aligned:
    // source = (x + 0.5) · source_size / size − 0.5.
    const Level& above = levels_[static_cast<std::size_t>(l - 1)];
    auto table = [](int size, int source_size, std::vector<std::int32_t>& index, std::vector<std::uint16_t>& weight) {
      index.resize(static_cast<std::size_t>(size));
      weight.resize(static_cast<std::size_t>(size));
      const double ratio = static_cast<double>(source_size) / size;
      for (int i = 0; i < size; ++i) {
        const double source = std::max((i + 0.5) * ratio - 0.5, 0.0);
        int i0 = std::min(static_cast<int>(source), source_size - 2);
        const double fraction = std::clamp(source - i0, 0.0, 1.0);
        index[static_cast<std::size_t>(i)] = i0;
        weight[static_cast<std::size_t>(i)] = static_cast<std::uint16_t>(std::lround(fraction * 256.0));
      }
    };
    table(level.width, above.width, level.source_x, level.weight_x);
    table(level.height, above.height, level.source_y, level.weight_y);
  }
  stride_ = width;
  level_smoothed_.assign(levels_.size(), 0);
  // Vector loads of the last row may read up to one block past it.
  const std::size_t pixels = rows * static_cast<std::size_t>(width) + kLanes;
  pyramid_.assign(pixels, 0);
  smoothed_.assign(pixels, 0);
  scratch_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) + kLanes, 0);
  scores_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) + kLanes, 0);
  row_.assign(static_cast<std::size_t>(width) + kLanes, 0);
  // At most one candidate per scanned pixel.
  candidates_.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));

  // The steered pattern as offsets in the shared row stride, one table per angle step.
  const auto& tests = pattern();
  steered_offsets_.resize(static_cast<std::size_t>(kAngleBins) * kTests * 2);
  for (int bin = 0; bin < kAngleBins; ++bin) {
    const double angle = 2.0 * std::numbers::pi * bin / kAngleBins;
    const double c = std::cos(angle);
    const double s = std::sin(angle);
    std::int32_t* offsets = &steered_offsets_[static_cast<std::size_t>(bin) * kTests * 2];
    for (int k = 0; k < kTests; ++k) {
      const Test& t = tests[static_cast<std::size_t>(k)];
      auto offset = [&](float fx, float fy) {
        const auto x = static_cast<double>(fx);
        const auto y = static_cast<double>(fy);
        const auto u = static_cast<std::int32_t>(std::lround(c * x - s * y));
        const auto v = static_cast<std::int32_t>(std::lround(s * x + c * y));
        return v * stride_ + u;
      };
      offsets[2 * k] = offset(t.ax, t.ay);
      offsets[2 * k + 1] = offset(t.bx, t.by);
    }
  }
}

cv::Mat OrbExtractor::level_image(int level) const {
  const Level& l = levels_[static_cast<std::size_t>(level)];
  return {l.height, l.width, CV_8UC1, const_cast<std::uint8_t*>(pyramid_.data() + l.offset),
          static_cast<std::size_t>(stride_)};
}

void OrbExtractor::build_level(std::size_t index) {
  const Level& level = levels_[index];
  const Level& above = levels_[index - 1];
  const std::uint8_t* source = pyramid_.data() + above.offset;
  std::uint8_t* target = pyramid_.data() + level.offset;
  std::uint16_t* row = row_.data();
  // Raw pointers: the byte stores below may alias anything, so a vector's members would be
  // reloaded on every pixel.
  const std::int32_t* source_x = level.source_x.data();
  const std::uint16_t* weight_x = level.weight_x.data();
  const std::ptrdiff_t stride = stride_;
  for (int y = 0; y < level.height; ++y) {
    const std::uint8_t* top = source + static_cast<std::ptrdiff_t>(level.source_y[static_cast<std::size_t>(y)]) * stride;
    const std::uint8_t* bottom = top + stride;
    const auto w_bottom = level.weight_y[static_cast<std::size_t>(y)];
    const auto w_top = static_cast<std::uint16_t>(256 - w_bottom);
    // Vertical first, over whole rows (vectorises); then horizontal through the column table.
    for (int x = 0; x < above.width; ++x) {
      row[x] = static_cast<std::uint16_t>(top[x] * w_top + bottom[x] * w_bottom);
    }
    std::uint8_t* out = target + static_cast<std::ptrdiff_t>(y) * stride;
    const int width = level.width;
    for (int x = 0; x < width; ++x) {
      const auto x0 = source_x[x];
      const std::uint32_t w_right = weight_x[x];
      const std::uint32_t value = row[x0] * (256U - w_right) + row[x0 + 1] * w_right;
      out[x] = static_cast<std::uint8_t>((value + 32768U) >> 16U);
    }
  }
}

void OrbExtractor::detect(const Level& level) {
  const std::uint8_t* image = pyramid_.data() + level.offset;
  const int border = settings_.border_px;
  const auto threshold = broadcast(static_cast<std::uint8_t>(settings_.fast_threshold));
  std::ptrdiff_t circle[16];
  for (int k = 0; k < 16; ++k) circle[k] = static_cast<std::ptrdiff_t>(kCircle[k][1]) * stride_ + kCircle[k][0];
  Bytes lane_index;
  for (int i = 0; i < kLanes; ++i) lane_index[i] = static_cast<std::uint8_t>(i);

  std::memset(scores_.data(), 0, static_cast<std::size_t>(level.height) * static_cast<std::size_t>(stride_));
  std::size_t count = 0;
  const int x_end = level.width - border;
  for (int y = border; y < level.height - border; ++y) {
    const std::uint8_t* row = image + static_cast<std::ptrdiff_t>(y) * stride_;
    std::uint8_t* score_row = scores_.data() + static_cast<std::ptrdiff_t>(y) * stride_;
    for (int x = border; x < x_end; x += kLanes) {
      // The last block of a row is moved left to end at the border; lanes already scanned drop out.
      const int start = std::min(x, x_end - kLanes);
      const Bytes lanes = ~greater(broadcast(static_cast<std::uint8_t>(x - start)), lane_index);
      const std::uint8_t* p = row + start;
      const Bytes centre = load(p);
      // A 9-pixel arc holds two neighbouring compass points: test those first, against the
      // saturated bounds centre ± threshold.
      const Bytes high = centre + lane_min(threshold, ~centre);
      const Bytes low = centre - lane_min(threshold, centre);
      auto brighter_than_high = [&](const std::uint8_t* q) {
        const Bytes c = load(q);
        return reinterpret_cast<Bytes>(lane_max(c, high) != high);
      };
      auto darker_than_low = [&](const std::uint8_t* q) {
        const Bytes c = load(q);
        return reinterpret_cast<Bytes>(lane_min(c, low) != low);
      };
      const Bytes bn = brighter_than_high(p + circle[0]);
      const Bytes be = brighter_than_high(p + circle[4]);
      const Bytes bs = brighter_than_high(p + circle[8]);
      const Bytes bw = brighter_than_high(p + circle[12]);
      const Bytes dn = darker_than_low(p + circle[0]);
      const Bytes de = darker_than_low(p + circle[4]);
      const Bytes ds = darker_than_low(p + circle[8]);
      const Bytes dw = darker_than_low(p + circle[12]);
      const Bytes possible = ((bn & be) | (be & bs) | (bs & bw) | (bw & bn) | (dn & de) | (de & ds) | (ds & dw) |
                              (dw & dn)) & lanes;
      if (!any_lane(possible)) continue;
      Bytes brighter[16];
      Bytes darker[16];
#pragma GCC unroll 16
      for (int k = 0; k < 16; ++k) {
        const Bytes c = load(p + circle[k]);
        brighter[k] = positive_difference(c, centre);
        darker[k] = positive_difference(centre, c);
      }
      // The score: the largest threshold at which the pixel is still a corner.
      const Bytes score = lane_max(best_arc_minimum(brighter), best_arc_minimum(darker));
      const Bytes corner = greater(score, threshold) & lanes;
      if (!any_lane(corner)) continue;
      std::uint8_t lane_scores[kLanes];
      std::uint8_t lane_corner[kLanes];
      std::memcpy(lane_scores, &score, kLanes);
      std::memcpy(lane_corner, &corner, kLanes);
      for (int i = 0; i < kLanes; ++i) {
        if (lane_corner[i] == 0) continue;
        score_row[start + i] = lane_scores[i];
        candidates_[count++] = {static_cast<std::int16_t>(start + i), static_cast<std::int16_t>(y),
                                static_cast<float>(lane_scores[i])};
      }
    }
  }
  candidate_count_ = count;
}

void OrbExtractor::suppress_non_maxima() {
  // A corner survives when its score beats those above and to the left and is at least those
  // below and to the right: of two equal neighbours exactly one is kept.
  std::size_t kept = 0;
  for (std::size_t i = 0; i < candidate_count_; ++i) {
    const Candidate c = candidates_[i];
    const std::uint8_t* s = scores_.data() + static_cast<std::ptrdiff_t>(c.y) * stride_ + c.x;
    const std::uint8_t v = *s;
    const bool maximum = v > s[-stride_ - 1] && v > s[-stride_] && v > s[-stride_ + 1] && v > s[-1] && v >= s[1] &&
                         v >= s[stride_ - 1] && v >= s[stride_] && v >= s[stride_ + 1];
    if (maximum) candidates_[kept++] = c;
  }
  candidate_count_ = kept;
}

float OrbExtractor::harris(const std::uint8_t* centre) const {
  const std::ptrdiff_t s = stride_;
  std::int32_t xx = 0;
  std::int32_t yy = 0;
  std::int32_t xy = 0;
  for (int dy = -kHarrisHalfWindow; dy <= kHarrisHalfWindow; ++dy) {
    const std::uint8_t* p = centre + dy * s - kHarrisHalfWindow;
    for (int dx = 0; dx < 2 * kHarrisHalfWindow + 1; ++dx, ++p) {
      // Sobel gradients.
      const int gx = (p[-s + 1] - p[-s - 1]) + 2 * (p[1] - p[-1]) + (p[s + 1] - p[s - 1]);
      const int gy = (p[s - 1] - p[-s - 1]) + 2 * (p[s] - p[-s]) + (p[s + 1] - p[-s + 1]);
      xx += gx * gx;
      yy += gy * gy;
      xy += gx * gy;
    }
  }
  // Mean over the window of gradients scaled to [−1, 1] (a Sobel response is at most 4 · 255).
  constexpr float kNorm = 1.0F / (49.0F * 1020.0F * 1020.0F);
  const float a = static_cast<float>(xx) * kNorm;
  const float b = static_cast<float>(yy) * kNorm;
  const float c = static_cast<float>(xy) * kNorm;
  return a * b - c * c - kHarrisK * (a + b) * (a + b);
}

float OrbExtractor::orientation(const std::uint8_t* centre) const {
  std::int32_t m10 = 0;
  std::int32_t m01 = 0;
  for (int u = -kPatchRadius; u <= kPatchRadius; ++u) m10 += u * centre[u];
  // Rows ±v together: their x moments add, their y moments subtract.
  for (int v = 1; v <= kPatchRadius; ++v) {
    const int half = circle_half_width_[static_cast<std::size_t>(v)];
    const std::uint8_t* below = centre + static_cast<std::ptrdiff_t>(v) * stride_;
    const std::uint8_t* above = centre - static_cast<std::ptrdiff_t>(v) * stride_;
    std::int32_t difference = 0;
    for (int u = -half; u <= half; ++u) {
      m10 += u * (below[u] + above[u]);
      difference += below[u] - above[u];
    }
    m01 += v * difference;
  }
  return std::atan2(static_cast<float>(m01), static_cast<float>(m10));
}

void OrbExtractor::smooth(const Level& level) {
  const int width = level.width;
  const std::uint8_t* image = pyramid_.data() + level.offset;
  // Horizontal pass; edges replicate the outermost pixel.
  for (int y = 0; y < level.height; ++y) {
    const std::uint8_t* in = image + static_cast<std::ptrdiff_t>(y) * stride_;
    std::uint8_t* out = scratch_.data() + static_cast<std::ptrdiff_t>(y) * stride_;
    auto at = [&](int x) -> std::uint16_t { return in[std::clamp(x, 0, width - 1)]; };
    for (int x = 0; x < 3; ++x) {
      out[x] = static_cast<std::uint8_t>((kGauss0 * at(x) + kGauss1 * (at(x - 1) + at(x + 1)) +
                                          kGauss2 * (at(x - 2) + at(x + 2)) + kGauss3 * (at(x - 3) + at(x + 3)) + 128) >>
                                         8);
    }
    for (int x = 3; x < width - 3; ++x) {
      out[x] = static_cast<std::uint8_t>(
          (kGauss0 * in[x] + kGauss1 * (in[x - 1] + in[x + 1]) + kGauss2 * (in[x - 2] + in[x + 2]) +
           kGauss3 * (in[x - 3] + in[x + 3]) + 128) >>
          8);
    }
    for (int x = width - 3; x < width; ++x) {
      out[x] = static_cast<std::uint8_t>((kGauss0 * at(x) + kGauss1 * (at(x - 1) + at(x + 1)) +
                                          kGauss2 * (at(x - 2) + at(x + 2)) + kGauss3 * (at(x - 3) + at(x + 3)) + 128) >>
                                         8);
    }
  }
  // Vertical pass; edge rows replicate.
  std::uint8_t* target = smoothed_.data() + level.offset;
  for (int y = 0; y < level.height; ++y) {
    const std::uint8_t* r[7];
    for (int k = 0; k < 7; ++k) {
      r[k] = scratch_.data() + static_cast<std::ptrdiff_t>(std::clamp(y + k - 3, 0, level.height - 1)) * stride_;
    }
    std::uint8_t* out = target + static_cast<std::ptrdiff_t>(y) * stride_;
    for (int x = 0; x < width; ++x) {
      out[x] = static_cast<std::uint8_t>((kGauss0 * r[3][x] + kGauss1 * (r[2][x] + r[4][x]) +
                                          kGauss2 * (r[1][x] + r[5][x]) + kGauss3 * (r[0][x] + r[6][x]) + 128) >>
                                         8);
    }
  }
}

void OrbExtractor::describe(const std::uint8_t* centre, float angle_rad, std::uint8_t* descriptor) const {
  constexpr float kBinsPerRadian = static_cast<float>(kAngleBins / (2.0 * std::numbers::pi));
  int bin = static_cast<int>(std::lround(angle_rad * kBinsPerRadian)) % kAngleBins;
  if (bin < 0) bin += kAngleBins;
  const std::int32_t* offsets = &steered_offsets_[static_cast<std::size_t>(bin) * kTests * 2];
  for (int byte = 0; byte < kDescriptorBytes; ++byte) {
    unsigned value = 0;
    for (int bit = 0; bit < 8; ++bit) {
      const int k = 2 * (8 * byte + bit);
      value |= static_cast<unsigned>(centre[offsets[k]] < centre[offsets[k + 1]]) << static_cast<unsigned>(bit);
    }
    descriptor[byte] = static_cast<std::uint8_t>(value);
  }
}

void OrbExtractor::add_keypoint(std::size_t l, int x, int y, cv::Point2f pt, float response) {
  const Level& level = levels_[l];
  const std::ptrdiff_t at = static_cast<std::ptrdiff_t>(level.offset) + static_cast<std::ptrdiff_t>(y) * stride_ + x;
  const float angle = orientation(pyramid_.data() + at);
  describe(smoothed_.data() + at, angle, descriptor_storage_.ptr(static_cast<int>(keypoints_.size())));
  float degrees = angle * static_cast<float>(rad_to_deg(1.0));
  if (degrees < 0.0F) degrees += 360.0F;
  keypoints_.emplace_back(pt, static_cast<float>(2 * kPatchRadius + 1) * level.scale_x, degrees, response,
                          static_cast<int>(l));
}

bool OrbExtractor::load_image(const cv::Mat& gray) {
  keypoints_.clear();
  if (gray.empty() || gray.type() != CV_8UC1) return false;
  if (gray.cols != settings_.width || gray.rows != settings_.height) set_up(gray.cols, gray.rows);
  if (levels_.empty()) return false;
  for (int y = 0; y < gray.rows; ++y) {
    std::memcpy(pyramid_.data() + static_cast<std::ptrdiff_t>(y) * stride_, gray.ptr(y), static_cast<std::size_t>(gray.cols));
  }
  return true;
}

bool OrbExtractor::describe(const cv::Mat& gray, const std::vector<cv::KeyPoint>& detected, float base_size) {
  if (!load_image(gray)) return false;
  for (std::size_t l = 1; l < levels_.size(); ++l) build_level(l);
  level_smoothed_.assign(levels_.size(), 0);  // no allocation once sized: the level count is fixed
  const float log_factor = std::log(settings_.scale_factor);
  const int border = settings_.border_px;
  const auto cap = static_cast<std::size_t>(settings_.max_features);
  for (const cv::KeyPoint& kp : detected) {
    if (keypoints_.size() >= cap) break;
    const float scale = std::max(kp.size / base_size, 1.0F);
    const auto l = static_cast<std::size_t>(
        std::clamp(static_cast<int>(std::lround(std::log(scale) / log_factor)), 0, static_cast<int>(levels_.size()) - 1));
    const Level& level = levels_[l];
    const int x = static_cast<int>(std::lround((kp.pt.x + 0.5F) / level.scale_x - 0.5F));
    const int y = static_cast<int>(std::lround((kp.pt.y + 0.5F) / level.scale_y - 0.5F));
    if (x < border || y < border || x >= level.width - border || y >= level.height - border) continue;
    if (level_smoothed_[l] == 0) {
      smooth(level);
      level_smoothed_[l] = 1;
    }
    add_keypoint(l, x, y, kp.pt, kp.response);
  }
  return true;
}

bool OrbExtractor::extract(const cv::Mat& gray) {
  if (!load_image(gray)) return false;
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    if (l > 0) build_level(l);
    const Level& level = levels_[l];
    if (level.budget == 0) continue;
    detect(level);
    suppress_non_maxima();
    const auto budget = static_cast<std::size_t>(level.budget);
    auto begin = candidates_.begin();
    auto end = begin + static_cast<std::ptrdiff_t>(candidate_count_);
    auto by_score = [](const Candidate& a, const Candidate& b) { return a.score > b.score; };
    // ORB: the 2n best FAST corners, of them the n best by the Harris measure.
    if (candidate_count_ > 2 * budget) {
      end = begin + static_cast<std::ptrdiff_t>(2 * budget);
      std::nth_element(begin, end, begin + static_cast<std::ptrdiff_t>(candidate_count_), by_score);
    }
    const std::uint8_t* image = pyramid_.data() + level.offset;
    for (auto it = begin; it != end; ++it) {
      it->score = harris(image + static_cast<std::ptrdiff_t>(it->y) * stride_ + it->x);
    }
    if (end - begin > static_cast<std::ptrdiff_t>(budget)) {
      std::nth_element(begin, begin + static_cast<std::ptrdiff_t>(budget), end, by_score);
      end = begin + static_cast<std::ptrdiff_t>(budget);
    }
    if (begin == end) continue;
    smooth(level);
    for (auto it = begin; it != end; ++it) {
      add_keypoint(l, it->x, it->y,
                   cv::Point2f((static_cast<float>(it->x) + 0.5F) * level.scale_x - 0.5F,
                               (static_cast<float>(it->y) + 0.5F) * level.scale_y - 0.5F),
                   it->score);
    }
  }
  return true;
}

}  // namespace rankslam::slam
