#include "commands.hpp"

#include "rankslam/geometry/matching.hpp"
#include "rankslam/parallel/cpu_features.hpp"

namespace rankslam::app {

std::string vector_kernels() {
  // The portable loops may still be vectorised by the compiler for the build's baseline.
  std::string name = parallel::vector_target();
  if (geometry::DescriptorMatcher::cpu_has_vnni()) name += "+avx512vnni";
  return name;
}

}  // namespace rankslam::app
