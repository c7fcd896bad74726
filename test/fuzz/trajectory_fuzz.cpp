// TUM trajectory text as `eval` and the replay's ground truth read it: parsed or refused with a
// message naming the line, never a crash; every accepted pose is finite with a unit quaternion.
#include "fuzz_support.hpp"
#include "rankslam/eval/trajectory.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using rankslam::fuzz::require;
  const auto trajectory =
      rankslam::eval::parse_tum_trajectory(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz");
  if (!trajectory) {
    require(!trajectory.error().empty(), "a refusal says why");
    return 0;
  }
  for (const auto& pose : trajectory.value()) {
    require(std::isfinite(pose.stamp_s) && pose.T_world_cam.matrix().allFinite(), "an accepted pose is finite");
    require(std::abs(pose.T_world_cam.linear().determinant() - 1.0) < 1e-6, "an accepted rotation is proper");
  }
  const auto again = rankslam::eval::parse_tum_trajectory(rankslam::eval::format_tum_trajectory(trajectory.value()), "again");
  require(again.ok() && again.value().size() == trajectory.value().size(), "formatted poses parse again");
  return 0;
}
