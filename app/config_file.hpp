#pragma once

#include "rankslam/nav/wheel_odometry.hpp"
#include "rankslam/slam/config.hpp"

#include <filesystem>
#include <string>

namespace rankslam::app {

/// Overrides `config` with the `slam:` section of a YAML file. Unknown keys and out-of-range
/// values are errors naming the file and the key. Empty string on success.
[[nodiscard]] std::string load_slam_config(const std::filesystem::path& path, slam::SlamConfig& config);

/// Every effective parameter, one "slam.name = value unit  # doc" line each.
[[nodiscard]] std::string describe_slam_config(slam::SlamConfig config);

/// Parameters as a JSON object body ("name": value, ...), for the report.
[[nodiscard]] std::string slam_config_json(slam::SlamConfig config);

/// Overrides `config` with the `wheel_odometry:` section of a YAML file (noise and limits of the
/// wheel-encoder odometry), with the same rules as load_slam_config. Empty string on success.
[[nodiscard]] std::string load_wheel_config(const std::filesystem::path& path, nav::WheelOdometryConfig& config);

/// Every effective wheel odometry parameter, one "wheel_odometry.name = value unit  # doc" line each.
[[nodiscard]] std::string describe_wheel_config(nav::WheelOdometryConfig config);

/// What `replay` and `run` configure alike: the slam and wheel_odometry sections of `path` (the
/// defaults when empty) and the registration named `mode_name` (kDefaultMode when empty). kExitOk,
/// or the exit code after printing why not.
[[nodiscard]] int load_pipeline_config(const std::filesystem::path& path, const std::string& mode_name,
                                       slam::SlamConfig& slam_config, nav::WheelOdometryConfig& wheel_config);

/// Creates the output directory `dir`, removes what killed runs left there and test-writes a file,
/// so an unwritable `dir` stops the run before it starts; kExitOk, or kExitOutput after printing why not.
[[nodiscard]] int make_output_directory(const std::filesystem::path& dir);

}  // namespace rankslam::app
