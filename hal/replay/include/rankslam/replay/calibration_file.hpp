#pragma once

#include "rankslam/hal/calibration.hpp"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <string>

namespace rankslam::replay {

/// Reads a calibration.yaml (README, "calibration.yaml"). Error message naming file and field
/// on failure, empty on success.
[[nodiscard]] std::string load_calibration_yaml(const std::filesystem::path& path, hal::Calibration& calibration);

/// Reads a camera mounting as calibration.yaml writes T_base_cam: a map of `translation` (m) and
/// `rotation_xyzw` (a unit quaternion), found at `where`. Error naming the key path, empty on success.
[[nodiscard]] std::string read_mounting(const YAML::Node& node, const std::string& where, Eigen::Isometry3d& T_base_cam);

}  // namespace rankslam::replay
