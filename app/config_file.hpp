#pragma once

#include "rankslam/nav/wheel_odometry.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/wide/vlad.hpp"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <optional>
#include <set>
#include <string>

namespace rankslam::app {

/// Reads the configuration file `path` into `root` by the rules of every YAML file we read
/// (yaml::load_file: valid YAML, plain keys, none twice) and checks that each top-level section is
/// one the loaders here read (slam, geometry, wheel_odometry) or one of `other_sections`, which the
/// caller reads. Error naming the file and the section, empty on success.
[[nodiscard]] std::string read_config_file(const std::filesystem::path& path,
                                           const std::set<std::string>& other_sections, YAML::Node& root);

/// Overrides `config` with the `slam:` and `geometry:` sections of a YAML file. Unknown keys, and
/// values that are not finite numbers within their range, are errors naming the file and the key.
/// Empty string on success.
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
/// defaults when empty) and the registration named `mode_name` (kDefaultMode when empty). Sections
/// other than the pipeline's and `other_sections` (those the caller reads) are errors. kExitOk,
/// or the exit code after printing why not.
[[nodiscard]] int load_pipeline_config(const std::filesystem::path& path, const std::string& mode_name,
                                       slam::SlamConfig& slam_config, nav::WheelOdometryConfig& wheel_config,
                                       const std::set<std::string>& other_sections = {});

/// Creates the output directory `dir`, removes what killed runs left there and test-writes a file,
/// so an unwritable `dir` stops the run before it starts; kExitOk, or kExitOutput after printing why not.
[[nodiscard]] int make_output_directory(const std::filesystem::path& dir);

/// Reads the vocabulary file `path` into `vocabulary` (nothing when `path` is empty); an error
/// naming the file is printed and kExitInput returned when it cannot be read.
[[nodiscard]] int load_vocabulary(const std::filesystem::path& path, std::optional<wide::Vocabulary>& vocabulary);

}  // namespace rankslam::app
