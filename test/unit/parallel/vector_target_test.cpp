#include "rankslam/parallel/cpu_features.hpp"

#include <cstdio>
#include <string>

#include <gtest/gtest.h>

namespace rankslam::parallel {
namespace {

// The SIMD kernels run a vector target on every CPU this software is built for: x86-64 with
// SSSE3 or later (SSE4, AVX2, AVX-512) and every arm64 core (NEON; SVE is not compiled).
TEST(VectorTarget, NamesTheVectorUnitTheKernelsRun) {
  const std::string target = vector_target();
  std::printf("vector target: %s\n", target.c_str());
  if (portable_kernels_forced()) {
    EXPECT_EQ(target, "portable");
    EXPECT_FALSE(vector_kernels_enabled());
    return;
  }
  EXPECT_TRUE(vector_kernels_enabled());
#if defined(__aarch64__)
  EXPECT_EQ(target, "neon");
#elif defined(__x86_64__) && defined(__GNUC__)
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512vl")) {
    EXPECT_EQ(target.rfind("avx3", 0), 0U) << target;
  } else if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
    EXPECT_EQ(target, "avx2");
  } else if (__builtin_cpu_supports("sse4.2")) {
    EXPECT_EQ(target, "sse4");
  }
#endif
}

}  // namespace
}  // namespace rankslam::parallel
