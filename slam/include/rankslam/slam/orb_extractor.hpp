#pragma once

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace rankslam::slam {

/// What an OrbExtractor is sized for.
struct OrbExtractorSettings {
  int width = 640;            ///< Image width, px.
  int height = 480;           ///< Image height, px.
  int max_features = 1000;    ///< Keypoints per image at most, spread over the pyramid levels.
  float scale_factor = 1.2F;  ///< Pyramid scale between neighbouring levels.
  int levels = 8;             ///< Pyramid levels.
  int fast_threshold = 20;    ///< FAST: grey-level difference a circle pixel must exceed.
  /// Keypoints keep this distance, px at their own level, from the level's edges. The circular
  /// patch, the descriptor tests and the Harris window need 16 at least; larger values keep
  /// features away from the image edges, where registered depth is least reliable.
  int border_px = 16;
};

/// ORB features (Rublee et al., "ORB: an efficient alternative to SIFT or SURF", ICCV 2011) in
/// memory fixed at construction: extract() allocates nothing unless the image size changes.
///
/// Per pyramid level (each level resized from the previous one by 1/scale_factor, bilinear):
///  1. FAST-9 (Rosten & Drummond 2006): a pixel is a corner when 9 contiguous pixels of the
///     16-pixel Bresenham circle of radius 3 are all brighter than centre + threshold or all
///     darker than centre − threshold. Its score is the largest threshold at which it still is
///     one; a corner is kept when its score beats its 8 neighbours' (3×3 non-maximum
///     suppression).
///  2. The level's feature budget follows ORB: budgets fall geometrically with the level's
///     area scale, n_l ∝ scale_factor^−l, summing to max_features. The 2·n_l best FAST scores
///     are ranked by the Harris measure (7×7 window of Sobel gradients, k = 0.04) and the n_l
///     best are kept.
///  3. Orientation by the intensity centroid of a circular patch of radius 15: θ = atan2(m01,
///     m10) with m_pq = Σ x^p y^q I(x, y).
///  4. Steered BRIEF: 256 binary tests I(p) < I(q) on the level smoothed by a 7×7 Gaussian of
///     σ = 2, the test pattern rotated by θ (quantised to kAngleBins steps, as ORB does).
///
/// The test pattern is BRIEF's isotropic Gaussian sampling G II (Calonder et al. 2010): both
/// points of each pair drawn i.i.d. from N(0, S²/25) with S = 31, the patch size, redrawn when
/// outside the circle of radius 15 (which keeps every rotation inside the patch) or when both
/// points fall on the same pixel. The draws come from a fixed-seed SplitMix64 generator and
/// Box–Muller, so the pattern is the same on every platform and compiler.
///
/// Keypoint positions are in level-0 pixels: level pixel centres map with the levels' actual
/// size ratios. `octave` is the level, `angle` θ in degrees in [0, 360), `response` the Harris
/// measure of gradients scaled to [−1, 1], `size` the patch diameter in level-0 pixels.
class OrbExtractor {
 public:
  static constexpr int kDescriptorBytes = 32;
  static constexpr int kTests = 8 * kDescriptorBytes;
  static constexpr int kPatchRadius = 15;
  static constexpr int kAngleBins = 90;  // 4°: a steering error of 2° at most
  static constexpr std::uint64_t kPatternSeed = 0x0b5e55ed2011ULL;

  /// One binary test: I(a) < I(b), offsets in pixels from the keypoint (x right, y down).
  struct Test {
    float ax, ay, bx, by;
  };

  /// Set-up: allocates every buffer the extraction needs.
  explicit OrbExtractor(const OrbExtractorSettings& settings);

  /// Detects and describes the features of `gray` (CV_8UC1). An image of another size than the
  /// set-up's re-sizes the buffers first (the only case that allocates). Returns false, with no
  /// features, for an image of another type or too small for one patch.
  bool extract(const cv::Mat& gray);
  /// The FAST threshold of the next extractions (clamped to 1..254; no allocation).
  void set_fast_threshold(int threshold);

  /// Describes keypoints found by another detector (ROS2D, docs/methods.md §15) the way extract()
  /// describes its own: each goes to the pyramid level nearest its scale (`size` / `base_size`
  /// level-0 pixels per level pixel), gets the intensity-centroid orientation there and the
  /// steered BRIEF descriptor; keypoints within the border of their level are dropped, and at
  /// most max_features are kept, in the given order. `octave` becomes the level, the position and
  /// response stay. Same size rules and return value as extract().
  bool describe(const cv::Mat& gray, const std::vector<cv::KeyPoint>& detected, float base_size);

  [[nodiscard]] const std::vector<cv::KeyPoint>& keypoints() const { return keypoints_; }
  /// CV_8UC1, one kDescriptorBytes row per keypoint: a view of memory the next extract() reuses.
  [[nodiscard]] cv::Mat descriptors() const {
    return descriptor_storage_.rowRange(0, static_cast<int>(keypoints_.size()));
  }
  [[nodiscard]] int levels() const { return static_cast<int>(levels_.size()); }
  /// Pyramid level `level` of the last extract(), unsmoothed: a view of reused memory.
  [[nodiscard]] cv::Mat level_image(int level) const;
  /// The set-up's per-level feature budgets (they sum to max_features).
  [[nodiscard]] int level_budget(int level) const { return levels_[static_cast<std::size_t>(level)].budget; }
  /// The test pattern, unrotated.
  [[nodiscard]] static const std::array<Test, kTests>& pattern();

 private:
  struct Level {
    int width = 0;
    int height = 0;
    int budget = 0;
    std::size_t offset = 0;   ///< First pixel in the pyramid buffers.
    float scale_x = 1.0F;     ///< Level-0 pixels per level pixel.
    float scale_y = 1.0F;
    std::vector<std::int32_t> source_x;  ///< Bilinear source column, from the level above.
    std::vector<std::uint16_t> weight_x; ///< Weight of source_x + 1, of 256.
    std::vector<std::int32_t> source_y;
    std::vector<std::uint16_t> weight_y;
  };
  struct Candidate {
    std::int16_t x;
    std::int16_t y;
    float score;  ///< FAST score, then the Harris measure.
  };

  void set_up(int width, int height);
  bool load_image(const cv::Mat& gray);
  void build_level(std::size_t level);
  /// Orientation and steered BRIEF of level `l`'s pixel (x, y) (its level smoothed), appended as
  /// a keypoint at `pt` in level-0 pixels.
  void add_keypoint(std::size_t l, int x, int y, cv::Point2f pt, float response);
  void detect(const Level& level);
  void suppress_non_maxima();
  float harris(const std::uint8_t* centre) const;
  float orientation(const std::uint8_t* centre) const;
  void smooth(const Level& level);
  void describe(const std::uint8_t* centre, float angle_rad, std::uint8_t* descriptor) const;

  OrbExtractorSettings settings_;
  int stride_ = 0;  ///< Row stride shared by every level: one steered pattern table serves all.
  std::vector<Level> levels_;
  std::vector<std::uint8_t> pyramid_;   ///< Unsmoothed levels.
  std::vector<std::uint8_t> smoothed_;  ///< Gaussian-smoothed levels, for the descriptors.
  std::vector<std::uint8_t> scratch_;   ///< Horizontal pass of the smoothing.
  std::vector<std::uint16_t> row_;      ///< Vertical pass of the resize.
  std::vector<std::uint8_t> scores_;    ///< FAST scores of the level being detected.
  std::vector<Candidate> candidates_;
  std::size_t candidate_count_ = 0;
  std::array<int, kPatchRadius + 1> circle_half_width_{};
  std::vector<std::int32_t> steered_offsets_;  ///< kAngleBins × kTests × 2 offsets.
  std::vector<cv::KeyPoint> keypoints_;
  std::vector<std::uint8_t> level_smoothed_;  ///< describe(): levels smoothed for this image
  cv::Mat descriptor_storage_;
};

}  // namespace rankslam::slam
