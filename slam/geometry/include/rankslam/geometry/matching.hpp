#pragma once

// Mutual nearest-neighbour matching of L2-normalised descriptors (ALGORITHMS.md §3.6): a pair
// (a, b) is kept when b is a's nearest neighbour among B and a is b's among A.
//
// Exhaustive, not a tree: for unit vectors ‖a − b‖² = 2 − 2·a·b, so both nearest-neighbour
// directions come from one pass over the dot products, computed in register blocks (AVX2 + FMA
// when the CPU has it, chosen at run time; portable code otherwise). For ~400 × 400 SHOT
// descriptors this measures several times faster than nanoflann's k-d tree in 352 dimensions,
// where a tree degenerates to visiting most leaves (test/perf/geometry, BM_Match*).

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rankslam/parallel/thread_team.hpp"

namespace rankslam::geometry {

/// One mutual match: indices into the two descriptor sets and their Euclidean distance.
struct DescriptorMatch {
  int a = 0;
  int b = 0;
  float distance = 0.0F;
};

class DescriptorMatcher {
 public:
  enum class Kernel : std::uint8_t {
    kBest,      ///< AVX2 + FMA when the CPU has it, else portable.
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

  /// True when this CPU can run the AVX2 + FMA kernel.
  [[nodiscard]] static bool cpu_has_avx2();
  /// True when this matcher uses the AVX2 + FMA kernel.
  [[nodiscard]] bool uses_avx2() const { return use_avx2_; }

 private:
  int capacity_ = 0;
  bool use_avx2_ = false;
  int dimension_ = 0;
  parallel::ThreadTeam* team_ = nullptr;
  std::vector<float> best_of_a_;  // best similarity per row of A
  std::vector<int> arg_of_a_;
  std::vector<float> best_of_b_;  // per thread of the team: capacity_ values each
  std::vector<int> arg_of_b_;
};

}  // namespace rankslam::geometry
