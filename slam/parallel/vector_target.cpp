// The vector target that the Highway kernels dispatch to on this CPU: one HWY_EXPORT table like
// theirs, compiled for the same targets, so the name is the one they run.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "vector_target.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "rankslam/parallel/cpu_features.hpp"

#include <cctype>
#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace rankslam::parallel::HWY_NAMESPACE {

std::int64_t CompiledTarget() { return HWY_TARGET; }

}  // namespace rankslam::parallel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace rankslam::parallel {

HWY_EXPORT(CompiledTarget);

namespace {
std::int64_t chosen_target() {
  static const std::int64_t target = HWY_DYNAMIC_DISPATCH(CompiledTarget)();
  return target;
}
}  // namespace

bool vector_kernels_enabled() {
  static const bool enabled = !portable_kernels_forced() && chosen_target() != HWY_SCALAR &&
                              chosen_target() != HWY_EMU128;
  return enabled;
}

std::string vector_target() {
  if (!vector_kernels_enabled()) return "portable";
  std::string name = hwy::TargetName(chosen_target());
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

}  // namespace rankslam::parallel
#endif
