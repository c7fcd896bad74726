#pragma once

#include "rankslam/hal/calibration.hpp"

#include <filesystem>
#include <string>

namespace rankslam::replay {

/// Reads a calibration.yaml (README, "calibration.yaml"). Error message naming file and field
/// on failure, empty on success.
[[nodiscard]] std::string load_calibration_yaml(const std::filesystem::path& path, hal::Calibration& calibration);

}  // namespace rankslam::replay
