#pragma once

#include <cmath>
#include <cstdint>
#include <random>

namespace rankslam::sim::detail {

/// splitmix64 finaliser: a counter-based hash, so per-pixel noise needs no shared generator
/// state and the output cannot depend on thread scheduling.
[[nodiscard]] constexpr std::uint64_t mix64(std::uint64_t x) {
  x ^= x >> 30U;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27U;
  x *= 0x94d049bb133111ebULL;
  x ^= x >> 31U;
  return x;
}

/// Key of one noise stream (stream id, frame) for one seed.
[[nodiscard]] constexpr std::uint64_t stream_key(std::uint64_t seed, std::uint64_t stream, std::uint64_t frame) {
  return mix64(mix64(seed ^ 0x5851f42d4c957f2dULL) ^ (stream * 0x9e3779b97f4a7c15ULL) ^
               (frame * 0xd6e8feb86659fd93ULL));
}

/// Hash of element `index` in a stream.
[[nodiscard]] constexpr std::uint64_t element_hash(std::uint64_t key, std::uint64_t index) {
  return mix64(key + index * 0x9e3779b97f4a7c15ULL);
}

/// Sequential generator with portable uniform draws (the standard distributions are
/// implementation-defined, these are not).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}
  /// Uniform in [0, 1).
  double uniform() { return static_cast<double>(engine_() >> 11U) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Uniform integer in [lo, hi].
  int integer(int lo, int hi) {
    return lo + static_cast<int>(engine_() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  bool chance(double p) { return uniform() < p; }
  /// Standard normal (Box–Muller, one value per call).
  double gaussian() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }
  std::uint64_t next() { return engine_(); }

 private:
  std::mt19937_64 engine_;
};

}  // namespace rankslam::sim::detail
