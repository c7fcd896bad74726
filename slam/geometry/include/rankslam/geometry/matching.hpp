#pragma once

// Mutual nearest-neighbour matching of L2-normalised descriptors (docs/methods.md §5): a pair
// (a, b) is kept when b is a's nearest neighbour among B and a is b's among A.
//
// Exhaustive, not a tree: for unit vectors ‖a − b‖² = 2 − 2·a·b, so both nearest-neighbour
// directions come from one pass over the dot products, computed in register blocks (the vector
// kernel where the CPU has a vector target, chosen at run time; portable code otherwise). For ~400 × 400 SHOT
// descriptors this measures several times faster than nanoflann's k-d tree in 352 dimensions,
// where a tree degenerates to visiting most leaves (test/perf/geometry, BM_Match*).
//
// On CPUs with AVX-512 VNNI, and for non-negative descriptors (SHOT's histograms), that pass
// runs on 8-bit copies instead (each descriptor scaled to its largest value), four times as
// many multiply-adds per instruction, and gives every dot product within a bound ε (per pair) of
// the float one. Only the pairs whose upper bound reaches their row's or column's largest lower
// bound can be its best; those few are computed again in float, summed exactly as the float
// kernel sums them, so the matches are the float kernel's, ties included.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rankslam/parallel/thread_team.hpp"

#include <opencv2/core/mat.hpp>

namespace rankslam::geometry {

/// Nearest neighbours of 256-bit binary descriptors (ORB's: rows of 32 bytes) by Hamming
/// distance, both ways in one pass over the distance matrix: each source's nearest target and
/// each target's nearest source, ties to the lower index. The vector kernel (where the CPU has
/// one) compares a source with a vector of targets at once, the targets' words held as four
/// planes; the portable loop covers the rest. Integer distances: the same values either way.
class HammingNearest {
 public:
  static constexpr std::uint32_t kNone = 0xffffffffU;

  /// Set-up (allocates): sets of up to `max_descriptors` rows, so that scan() allocates nothing
  /// for sets no larger (a larger set grows the scratch). `vector` false: the portable loop only.
  void reserve(std::size_t max_descriptors, bool vector = true);
  /// Both sets CV_8UC1 with 32 columns.
  void scan(const cv::Mat& source, const cv::Mat& target);

  /// Source i's nearest target (kNone for an empty target set).
  [[nodiscard]] std::uint32_t nearest_target(int i) const {
    return static_cast<std::uint32_t>(row_arg_[static_cast<std::size_t>(i)]);
  }
  /// Target j's nearest source, and their distance.
  [[nodiscard]] std::uint32_t nearest_source(int j) const {
    return static_cast<std::uint32_t>(col_arg_[static_cast<std::size_t>(j)]);
  }
  [[nodiscard]] std::uint32_t source_distance(int j) const {
    return static_cast<std::uint32_t>(col_best_[static_cast<std::size_t>(j)]);
  }
  /// True when scan() runs the vector kernel.
  [[nodiscard]] bool uses_vector_kernel() const { return use_vector_; }

 private:
  bool use_vector_ = false;
  std::vector<std::uint64_t> source_words_;  // row after row, 4 words each
  std::vector<std::uint64_t> target_planes_;  // plane k: word k of every target (padded to 8)
  std::vector<std::int64_t> row_best_, row_arg_, col_best_, col_arg_;
};

/// One mutual match: indices into the two descriptor sets and their Euclidean distance.
struct DescriptorMatch {
  int a = 0;
  int b = 0;
  float distance = 0.0F;
};

class DescriptorMatcher {
 public:
  enum class Kernel : std::uint8_t {
    kBest,      ///< The 8-bit pass where it applies, else the vector kernel where the CPU has one, else portable.
    kFloat,     ///< The vector kernel where the CPU has one, else portable: the same matches as kBest.
    kPortable,  ///< Eigen fixed-size packets (SSE2 / NEON) only.
  };

  /// Set-up (allocates): up to max_descriptors per side, `dimension` floats per descriptor. With
  /// a team, each match shares A's rows among its threads (the same matches as without).
  [[nodiscard]] std::string configure(int max_descriptors, int dimension,
                                      Kernel kernel = Kernel::kBest,
                                      parallel::ThreadTeam* team = nullptr);
  [[nodiscard]] bool configured() const { return capacity_ > 0; }

  /// Per frame, no allocation: mutual nearest neighbours between A (count_a × dimension floats,
  /// row-major, unit L2 norm) and B. Writes at most out.size() matches, in ascending index of A,
  /// and returns how many; −1 when a count exceeds the capacity. Ties go to the lower index.
  int match(const float* a, int count_a, const float* b, int count_b,
            std::span<DescriptorMatch> out);

  /// True when this CPU runs the vector kernel (parallel::vector_kernels_enabled()).
  [[nodiscard]] static bool has_vector_kernel();
  /// True when this matcher uses the vector kernel.
  [[nodiscard]] bool uses_vector_kernel() const { return use_vector_; }
  /// True when this CPU can run the 8-bit (AVX-512 VNNI) pass.
  [[nodiscard]] static bool cpu_has_vnni();
  /// True when this matcher runs the 8-bit pass on non-negative descriptors.
  [[nodiscard]] bool uses_vnni() const { return use_vnni_; }

 private:
  // Each row's best column and each column's best row (best_of_a_ / arg_of_a_ and the first
  // entries of best_of_b_ / arg_of_b_): by the float kernels, or by the 8-bit pass and the float
  // values of its candidates (false, nothing done, where it does not apply).
  void match_float(const float* a, int count_a, const float* b, int count_b);
  bool match_8bit(const float* a, int count_a, const float* b, int count_b);
  // The other threads' bests of the columns into thread 0's, ties to the lower row.
  void merge_column_bests(int count_b);

  int capacity_ = 0;
  bool use_vector_ = false;
  bool use_vnni_ = false;
  int dimension_ = 0;
  parallel::ThreadTeam* team_ = nullptr;
  std::vector<float> best_of_a_;  // best similarity per row of A
  std::vector<int> arg_of_a_;
  std::vector<float> best_of_b_;  // per thread of the team: capacity_ values each
  std::vector<int> arg_of_b_;
  // The 8-bit pass: each side's descriptors as bytes (rows padded to whole 32-byte steps, A to
  // whole blocks of 3 rows, B of 8), their scales back to float and L1 norms, every pair's
  // approximate dot product (row-major, approximate_stride_ columns), and per thread the largest
  // lower bound of each column over the rows it scanned and a row's candidate columns.
  int quantised_dimension_ = 0;
  int approximate_stride_ = 0;
  std::vector<std::uint8_t> quantised_a_;
  std::vector<std::int8_t> quantised_b_;
  std::vector<float> inverse_scale_a_, inverse_scale_b_, l1_a_, l1_b_, norm_a_, norm_b_;
  std::vector<float> approximate_;
  std::vector<float> column_lower_;
  std::vector<int> candidates_;
};

}  // namespace rankslam::geometry
