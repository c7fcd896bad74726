#pragma once

#include <cstdlib>
#include <cstring>

namespace rankslam::parallel {

/// RANKSLAM_PORTABLE_KERNELS set (to anything but "0") in the environment: every vector kernel
/// gives way to its portable loop, as on a CPU without the vector unit (asked once). For
/// measuring what the vector kernels win; results are the same within each kernel's tolerance.
inline bool portable_kernels_forced() {
  static const bool forced = [] {
    const char* value = std::getenv("RANKSLAM_PORTABLE_KERNELS");
    return value != nullptr && value[0] != '\0' && std::strcmp(value, "0") != 0;
  }();
  return forced;
}

/// The CPU runs AVX2 (asked once). Vector kernels are compiled with target("avx2") beside their
/// portable loops and chosen at run time by this, so one x86-64 build serves every CPU. False
/// where there is no such kernel (arm64, other compilers) or portable_kernels_forced().
inline bool cpu_has_avx2() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has = __builtin_cpu_supports("avx2") && !portable_kernels_forced();
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
