#pragma once

namespace rankslam::parallel {

/// The CPU runs AVX2 (asked once). Vector kernels are compiled with target("avx2") beside their
/// portable loops and chosen at run time by this, so one x86-64 build serves every CPU. False
/// where there is no such kernel (arm64, other compilers).
inline bool cpu_has_avx2() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}

/// cpu_has_avx2() and FMA, for kernels that fuse their multiply-adds.
inline bool cpu_has_avx2_fma() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has = cpu_has_avx2() && __builtin_cpu_supports("fma");
  return has;
#else
  return false;
#endif
}

}  // namespace rankslam::parallel
