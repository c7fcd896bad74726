// The configuration files as `replay --config` and `run --config` read them: any bytes are
// refused with a message or accepted, never a crash or an escaped exception; what is accepted
// holds every parameter finite and within its documented range.
#include "config_file.hpp"
#include "fuzz_support.hpp"
#include "robot_config.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <type_traits>

namespace {

using rankslam::fuzz::require;

template <typename Config>
void require_in_range(Config& config) {
  config.visit_parameters([](auto /*name*/, auto& field, auto min, auto max, auto /*unit*/, auto /*doc*/) {
    using Field = std::remove_cvref_t<decltype(field)>;
    if constexpr (std::is_floating_point_v<Field>) require(std::isfinite(field), "an accepted parameter is finite");
    require(!(field < static_cast<Field>(min)) && !(field > static_cast<Field>(max)),
            "an accepted parameter lies within its range");
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace app = rankslam::app;
  const auto path = rankslam::fuzz::scratch_dir() / "config.yaml";
  rankslam::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));

  rankslam::slam::SlamConfig slam;
  if (app::load_slam_config(path, slam).empty()) {
    require_in_range(slam);
    require_in_range(slam.geometry);
  }
  rankslam::nav::WheelOdometryConfig wheels;
  if (app::load_wheel_config(path, wheels).empty()) require_in_range(wheels);
  app::RobotConfig robot;
  if (app::load_robot_config(path, robot).empty()) {
    require(std::isfinite(robot.replay_rate) && robot.replay_rate >= 0.0, "an accepted replay rate is finite");
    require(std::isfinite(robot.exit_after_end_s), "an accepted end delay is finite");
  }
  return 0;
}
