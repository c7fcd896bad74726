#pragma once

#include <cstdint>

namespace rankslam::robust {

/// PCG32 (O'Neill 2014, pcg32_random_r): 16 bytes of state, fast, and identical on every platform
/// and standard library, unlike the std:: distributions, so a seed reproduces a run anywhere.
class Pcg32 {
 public:
  explicit constexpr Pcg32(std::uint64_t seed, std::uint64_t stream = 0xda3e39cb94b95bdbULL)
      : inc_((stream << 1U) | 1U) {
    next();
    state_ += seed;
    next();
  }

  constexpr std::uint32_t next() {
    const std::uint64_t old = state_;
    state_ = old * 6364136223846793005ULL + inc_;
    const auto xorshifted = static_cast<std::uint32_t>(((old >> 18U) ^ old) >> 27U);
    const auto rot = static_cast<std::uint32_t>(old >> 59U);
    return (xorshifted >> rot) | (xorshifted << ((0U - rot) & 31U));
  }

  /// Uniform in [0, range), range > 0, without modulo bias (Lemire 2019).
  constexpr std::uint32_t bounded(std::uint32_t range) {
    std::uint64_t product = static_cast<std::uint64_t>(next()) * range;
    auto low = static_cast<std::uint32_t>(product);
    if (low < range) {
      const std::uint32_t threshold = (0U - range) % range;
      while (low < threshold) {
        product = static_cast<std::uint64_t>(next()) * range;
        low = static_cast<std::uint32_t>(product);
      }
    }
    return static_cast<std::uint32_t>(product >> 32U);
  }

  /// Uniform in [0, 1) with 53 random bits.
  constexpr double uniform01() {
    const std::uint64_t bits =
        (static_cast<std::uint64_t>(next()) << 21U) ^ (static_cast<std::uint64_t>(next()) >> 11U);
    return static_cast<double>(bits & ((std::uint64_t{1} << 53U) - 1U)) * 0x1.0p-53;
  }

 private:
  std::uint64_t state_ = 0;
  std::uint64_t inc_;
};

}  // namespace rankslam::robust
