#pragma once

#include <cstdlib>
#include <cstring>
#include <string>

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

/// The portable SIMD kernels (Highway, written once for every vector unit: SSE4, AVX2, AVX-512,
/// NEON) run a vector target on this CPU: dispatched at run time to the best one it has, false
/// where that is none or portable_kernels_forced(). Their callers run their portable loops then.
bool vector_kernels_enabled();

/// The target vector_kernels_enabled() dispatches to, lower case as Highway names it ("avx2",
/// "avx3_dl", "neon"), or "portable".
std::string vector_target();

}  // namespace rankslam::parallel
